#!/usr/bin/env bash
# Installs what Nimbus needs on Debian 12 besides Rust: the Vulkan loader, Mesa's
# lavapipe (a CPU Vulkan device), the Khronos validation layers, and the static
# shaderc / glslang / SPIRV-Tools libraries that build.rs links (see .cargo/config.toml).
set -euo pipefail

packages=(
    libvulkan1            # Vulkan loader (ash loads it at run time)
    mesa-vulkan-drivers   # lavapipe, the CPU device used in tests and CI
    vulkan-validationlayers
    libshaderc-dev        # libshaderc_combined.a
    glslang-dev           # libglslang.a, libSPIRV.a, libMachineIndependent.a, ...
    spirv-tools           # libSPIRV-Tools.a, libSPIRV-Tools-opt.a
    g++                   # the nv-flip test dependency builds C++
    pkg-config
)

if [ "$(id -u)" -eq 0 ]; then
    sudo=()
else
    sudo=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq --no-install-recommends "${packages[@]}"
