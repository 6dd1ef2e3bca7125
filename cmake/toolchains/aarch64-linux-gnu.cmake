# aarch64 Linux toolchain for the site gateway on arm64 boxes (Debian's crossbuild-essential-arm64
# and the :arm64 -dev packages of a multiarch install; scripts/install-deps --arm64). Used only
# through the `arm64` preset, which builds the gateway alone (LW_GATEWAY_ONLY).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
# Debian multiarch: the target's libraries and CMake/pkg-config files live in lib/aarch64-linux-gnu
# of the same prefix; arch-independent headers (Eigen, nlohmann-json) are shared with the build
# machine's.
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/aarch64-linux-gnu/pkgconfig:/usr/share/pkgconfig")
# Programs built here run on the build machine through qemu-user (man pages, tests), with the
# multiarch libc6:arm64 loader in /lib (not qemu's -L /usr/aarch64-linux-gnu: that cross libc mixed
# with the multiarch libraries hangs the gateway's first thread).
find_program(LW_QEMU_AARCH64 NAMES qemu-aarch64-static qemu-aarch64)
if(LW_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${LW_QEMU_AARCH64})
endif()
set(LW_DEB_ARCHITECTURE arm64)
