# Makefile fragment: the generic firmware (fw_main.c + a HAL) over any generated tree.
#
#   ROLLMPC_GEN := path/to/generated/tree       # the output of `rollmpc generate`
#   include path/to/firmware_stub/generic/rollmpc_fw.mk
#   CFLAGS += $(ROLLMPC_FW_CFLAGS)
#   SRCS   += $(ROLLMPC_FW_SRCS) $(ROLLMPC_FW_HAL_HOST)   # or $(ROLLMPC_FW_HAL_M4F)
#
# The prefix is read from the tree's <prefix>_config.h, so nothing about the design is
# restated here; a directory without one stops make with a one-line message.
ROLLMPC_FW_DIR := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
ROLLMPC_FW_CONFIG := $(firstword $(wildcard $(ROLLMPC_GEN)/*_config.h))
ifeq ($(ROLLMPC_FW_CONFIG),)
$(error $(ROLLMPC_GEN): no <prefix>_config.h, not a generated tree (rollmpc generate CONFIG -o DIR))
endif
ROLLMPC_FW_PREFIX := $(patsubst %_config.h,%,$(notdir $(ROLLMPC_FW_CONFIG)))
ROLLMPC_FW_UPPER := $(shell echo $(ROLLMPC_FW_PREFIX) | tr a-z A-Z)
# the prefix, and the solve time from the DWT cycle counter on Cortex-M (0 on the host)
ROLLMPC_FW_CFLAGS := -I$(ROLLMPC_GEN) -I$(ROLLMPC_FW_DIR) -ffp-contract=off \
    -DFW_PREFIX=$(ROLLMPC_FW_PREFIX) -DFW_PREFIX_UPPER=$(ROLLMPC_FW_UPPER) \
    '-DFW_HEADER="$(ROLLMPC_FW_PREFIX).h"' \
    -include $(ROLLMPC_FW_DIR)/../integration/common/rollglue_cycles.h \
    '-D$(ROLLMPC_FW_UPPER)_TIMESTAMP()=ROLLGLUE_CYCLES()'
ROLLMPC_FW_SRCS := $(ROLLMPC_FW_DIR)/fw_main.c $(wildcard $(ROLLMPC_GEN)/*.c)
ROLLMPC_FW_HAL_HOST := $(ROLLMPC_FW_DIR)/host/fw_hal_host.c
ROLLMPC_FW_HAL_M4F := $(ROLLMPC_FW_DIR)/m4f/fw_hal_m4f.c $(ROLLMPC_FW_DIR)/../m4f/startup_m4f.c
# the linker script INCLUDEs rollctl_memory.ld: the part's MEMORY (firmware.mk writes it
# from <prefix>_target.mk)
ROLLMPC_FW_LDSCRIPT := $(ROLLMPC_FW_DIR)/../m4f/cortex_m_generic.ld
