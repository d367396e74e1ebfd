# CMake fragment: the generic firmware (fw_main.c + a HAL) over any generated tree.
#
#   include(path/to/firmware_stub/generic/rollmpc_fw.cmake)
#   rollmpc_add_firmware(my_fw GEN path/to/generated/tree HAL host)   # or HAL m4f
#
# The prefix is read from the tree's <prefix>_config.h; for HAL m4f use an
# arm-none-eabi toolchain file and add the linker script ROLLMPC_FW_LDSCRIPT.
set(ROLLMPC_FW_DIR ${CMAKE_CURRENT_LIST_DIR})
set(ROLLMPC_FW_LDSCRIPT ${ROLLMPC_FW_DIR}/../m4f/cortex_m_generic.ld)  # INCLUDEs rollctl_memory.ld (the part's MEMORY; see firmware.mk)

function(rollmpc_add_firmware target)
	cmake_parse_arguments(FW "" "GEN;HAL" "" ${ARGN})
	file(GLOB config ${FW_GEN}/*_config.h)
	if(NOT config)
		message(FATAL_ERROR "${FW_GEN}: no <prefix>_config.h, not a generated tree (rollmpc generate CONFIG -o DIR)")
	endif()
	get_filename_component(prefix ${config} NAME)
	string(REGEX REPLACE "_config\\.h$" "" prefix ${prefix})
	string(TOUPPER ${prefix} upper)
	file(GLOB generated_sources ${FW_GEN}/*.c)
	if(FW_HAL STREQUAL "m4f")
		set(hal ${ROLLMPC_FW_DIR}/m4f/fw_hal_m4f.c ${ROLLMPC_FW_DIR}/../m4f/startup_m4f.c)
	else()
		set(hal ${ROLLMPC_FW_DIR}/host/fw_hal_host.c)
	endif()
	add_executable(${target} ${ROLLMPC_FW_DIR}/fw_main.c ${hal} ${generated_sources})
	target_include_directories(${target} PRIVATE ${FW_GEN} ${ROLLMPC_FW_DIR})
	target_compile_definitions(${target} PRIVATE FW_PREFIX=${prefix} FW_PREFIX_UPPER=${upper}
		FW_HEADER="${prefix}.h" "${upper}_TIMESTAMP()=ROLLGLUE_CYCLES()")
	# SHELL: keeps "-include <file>" one option through CMake's de-duplication
	target_compile_options(${target} PRIVATE -ffp-contract=off
		"SHELL:-include ${ROLLMPC_FW_DIR}/../integration/common/rollglue_cycles.h")
	target_link_libraries(${target} PRIVATE m)
endfunction()
