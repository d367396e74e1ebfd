# Firmware stub builds (used by the top-level `make firmware`, `make size`; also usable
# alone: make -f firmware_stub/firmware.mk [firmware|size|host] [FW_GEN=...] [FW_BUILD=...]).
#
#   firmware  image for the part FW_GEN was generated for: stub + HAL + startup + the
#             generated controller in FW_GEN (any tree: the roll module for a roll tree of
#             prefix rollmpc, else the generic main of generic/, at the tree's own period)
#   size      flash and static RAM of that image
#   host      host executable (stdin/stdout HAL) for closing the loop in a test
#
# The part comes from the tree: $(FW_GEN)/<prefix>_target.mk (rollmpc generate writes it
# from rollmpc_codegen/parts.py: the core's flags, the clock, the flash and RAM regions).
# Flags: those core flags and the target flags of `rollmpc report` (bit-exact with the
# host build), the project's strict warnings, PX4's C warnings and ArduPilot's frame
# limit, all -Werror.
#
# The linked image is checked against the design's target: section, which generate writes
# into FW_GEN's <prefix>_context.json (flash: text + data; static RAM: data + bss): beyond
# target.flash_kib or target.ram_kib the build fails and removes the image (the double
# tree of uav_roll linked 471 KiB of flash for a 256 KiB part without a word).  Override
# with FW_FLASH_KIB= / FW_RAM_KIB= (empty: no check), or FW_FORCE_SIZE=1 to keep the image
# with a warning.

FW_DIR ?= firmware_stub
FW_GEN ?= generated/uav_roll_f32
FW_BUILD ?= build/firmware
ARM_CC ?= arm-none-eabi-gcc
ARM_SIZE ?= arm-none-eabi-size
HOST_CC ?= gcc

# -fbuiltin after -ffreestanding keeps fabsf/sqrtf as VABS/VSQRT instead of library calls
FW_TARGET := -O2 -ffreestanding -fbuiltin -fno-math-errno -ffp-contract=off \
    -ffunction-sections -fdata-sections -fstack-usage
FW_WARN := -std=c99 -Wall -Wextra -Wpedantic -Wconversion -Wshadow -Wdouble-promotion -Werror \
    -Wfloat-equal -Wcast-align -Wstrict-prototypes -Wbad-function-cast -Wnested-externs \
    -fno-common -Wframe-larger-than=1300
# The app: the roll module (rollctl.c) for a roll tree of prefix rollmpc scheduled on the
# roll rate (or on nothing), else the generic main (generic/fw_main.c) that serves any
# design at its own sample period; FW_APP=generic forces the latter.
ROLLMPC_GEN := $(FW_GEN)
include $(FW_DIR)/generic/rollmpc_fw.mk
FW_PREFIX := $(ROLLMPC_FW_PREFIX)
FW_TARGET_MK := $(FW_GEN)/$(FW_PREFIX)_target.mk
include $(FW_TARGET_MK)
FW_MCU := $($(FW_PREFIX)_target_cflags)
FW_ROLL_TREE := $(and $(filter rollmpc,$(ROLLMPC_FW_PREFIX)),$(shell grep -l -E \
    '^#define ROLLMPC_N_OUTPUTS 1$$' $(ROLLMPC_FW_CONFIG)),$(if $(shell grep -l \
    -E '^#define ROLLMPC_N_SCHEDULE 0$$|^#define ROLLMPC_SCHEDULE_SIGNAL_ROLL_RATE 1$$' \
    $(ROLLMPC_FW_CONFIG)),yes))
FW_APP ?= $(if $(FW_ROLL_TREE),roll,generic)
ifeq ($(FW_APP),roll)
FW_INC := -I$(FW_GEN) -I$(FW_DIR) -include $(FW_DIR)/m4f/rollmpc_timestamp_m4f.h
FW_NAME := rollctl
FW_STUB_SRC := $(FW_DIR)/rollctl.c $(FW_DIR)/app_main.c
FW_M4F_SRC := $(FW_DIR)/m4f/rollctl_hal_m4f.c $(FW_DIR)/m4f/startup_m4f.c
FW_HOST_HAL := $(FW_DIR)/host/rollctl_hal_host.c
else
FW_INC := $(ROLLMPC_FW_CFLAGS)
FW_NAME := $(ROLLMPC_FW_PREFIX)_fw
FW_STUB_SRC := $(FW_DIR)/generic/fw_main.c
FW_M4F_SRC := $(ROLLMPC_FW_HAL_M4F)
FW_HOST_HAL := $(ROLLMPC_FW_HAL_HOST)
endif

FW_CONTEXT := $(firstword $(wildcard $(FW_GEN)/*_context.json))
# the number after "<key>": in the context (null, or no context: empty, no check)
fw_target = $(if $(FW_CONTEXT),$(shell sed -n 's/^ *"$(1)": *\([0-9][0-9.]*\).*/\1/p' $(FW_CONTEXT) | head -n 1))
FW_FLASH_KIB ?= $(call fw_target,flash_kib)
FW_RAM_KIB ?= $(call fw_target,ram_kib)
FW_FORCE_SIZE ?=

FW_CORE := $($(FW_PREFIX)_target_core_short)
FW_ELF := $(FW_BUILD)/$(FW_NAME)_$(FW_CORE).elf
FW_MEMORY := $(FW_BUILD)/rollctl_memory.ld
FW_HOST := $(FW_BUILD)/$(FW_NAME)_host
FW_GEN_SRC := $(wildcard $(FW_GEN)/*.c)
FW_HDR := $(wildcard $(FW_GEN)/*.h) $(FW_DIR)/rollctl.h $(FW_DIR)/rollctl_hal.h \
    $(FW_DIR)/integration/common/rollglue_cycles.h \
    $(FW_DIR)/m4f/rollmpc_timestamp_m4f.h $(wildcard $(FW_DIR)/generic/*.h)
FW_OBJ := $(addprefix $(FW_BUILD)/obj/,$(notdir $(FW_GEN_SRC:.c=.o) $(FW_STUB_SRC:.c=.o) \
    $(FW_M4F_SRC:.c=.o)))

vpath %.c $(FW_GEN) $(FW_DIR) $(FW_DIR)/m4f $(FW_DIR)/generic $(FW_DIR)/generic/m4f

.PHONY: firmware size host

firmware: $(FW_ELF)

$(FW_BUILD)/obj/%.o: %.c $(FW_HDR) $(FW_TARGET_MK) | $(FW_BUILD)/obj
	$(ARM_CC) $(FW_MCU) $(FW_TARGET) $(FW_WARN) -DROLLCTL_CPU_HZ=$($(FW_PREFIX)_target_cpu_hz)u \
	    -DFW_CPU_HZ=$($(FW_PREFIX)_target_cpu_hz)u \
	    $(FW_INC) -c $< -o $@

$(FW_BUILD)/obj:
	mkdir -p $@

# the part's regions, which the generic linker script INCLUDEs
$(FW_MEMORY): $(FW_TARGET_MK) | $(FW_BUILD)/obj
	printf 'MEMORY\n{\n    FLASH (rx)  : ORIGIN = %s, LENGTH = %sK\n    RAM   (rwx) : ORIGIN = %s, LENGTH = %sK\n}\n' \
	    $($(FW_PREFIX)_target_flash_origin) $($(FW_PREFIX)_target_flash_kib) \
	    $($(FW_PREFIX)_target_ram_origin) $($(FW_PREFIX)_target_ram_kib) > $@

$(FW_ELF): $(FW_OBJ) $(FW_DIR)/m4f/cortex_m_generic.ld $(FW_MEMORY)
	$(ARM_CC) $(FW_MCU) -nostartfiles --specs=nano.specs -Wl,--gc-sections -L$(FW_BUILD) \
	    -T $(FW_DIR)/m4f/cortex_m_generic.ld -Wl,-Map=$(FW_BUILD)/$(FW_NAME)_$(FW_CORE).map \
	    -o $@ $(FW_OBJ) -lm
	@$(ARM_SIZE) $@ | awk -v flash_kib="$(FW_FLASH_KIB)" -v ram_kib="$(FW_RAM_KIB)" \
	    -v force="$(FW_FORCE_SIZE)" -v gen="$(FW_GEN)" 'NR == 2 { \
	    flash = $$1 + $$2; ram = $$2 + $$3; bad = 0; \
	    what = force == "" ? "error" : "warning"; \
	    if (flash_kib != "" && flash > flash_kib * 1024) { bad = 1; \
	        printf "firmware: %s: flash %d B (%.1f KiB) above target.flash_kib = %s of %s\n", \
	            what, flash, flash / 1024, flash_kib, gen > "/dev/stderr" } \
	    if (ram_kib != "" && ram > ram_kib * 1024) { bad = 1; \
	        printf "firmware: %s: static RAM %d B (%.1f KiB) above target.ram_kib = %s of %s\n", \
	            what, ram, ram / 1024, ram_kib, gen > "/dev/stderr" } \
	    if (bad && force == "") { \
	        print "firmware: a double tree? generate --precision float; FW_FORCE_SIZE=1 keeps the image" > "/dev/stderr"; \
	        exit 1 } }' || { rm -f $@; exit 1; }
	@echo "firmware: $@"

size: $(FW_ELF)
	@$(ARM_SIZE) $(FW_ELF)
	@$(ARM_SIZE) $(FW_ELF) | awk 'NR == 2 { printf "flash %d B (text + data), static RAM %d B (data + bss) of %s\n", $$1 + $$2, $$2 + $$3, $$6 }'

host: $(FW_HOST)

$(FW_HOST): $(FW_GEN_SRC) $(FW_STUB_SRC) $(FW_HOST_HAL) $(FW_HDR)
	@mkdir -p $(FW_BUILD)
	$(HOST_CC) -O2 -ffp-contract=off $(FW_WARN) $(FW_INC) -o $@ $(FW_GEN_SRC) $(FW_STUB_SRC) \
	    $(FW_HOST_HAL) -lm
