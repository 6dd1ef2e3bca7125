# arm-none-eabi toolchain (Debian gcc-arm-none-eabi + newlib). Used only through the `cross` preset.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(LW_MCU_CPU "cortex-m4" CACHE STRING "Target Cortex-M core")

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
set(CMAKE_OBJCOPY arm-none-eabi-objcopy CACHE FILEPATH "")
set(CMAKE_SIZE arm-none-eabi-size CACHE FILEPATH "")

# Static libraries only while probing the compiler: there is no OS to link a test program against.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(LW_ARCH_FLAGS "-mcpu=${LW_MCU_CPU} -mthumb")
set(CMAKE_C_FLAGS_INIT "${LW_ARCH_FLAGS}")
set(CMAKE_CXX_FLAGS_INIT "${LW_ARCH_FLAGS}")
set(CMAKE_ASM_FLAGS_INIT "${LW_ARCH_FLAGS}")
set(CMAKE_EXE_LINKER_FLAGS_INIT "${LW_ARCH_FLAGS} -specs=nano.specs -specs=nosys.specs -Wl,--gc-sections -Wl,--print-memory-usage")

set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
