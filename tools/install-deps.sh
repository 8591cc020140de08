#!/usr/bin/env bash
# Installs what Nimbus needs on Debian 12: the Vulkan loader, Mesa's lavapipe (a CPU
# Vulkan device), the Khronos validation layers, the static shaderc / glslang /
# SPIRV-Tools libraries that build.rs links (see .cargo/config.toml), OpenVDB's Python
# module and tools for the .vdb reader's tests (tools/make_test_vdbs.py), Slurm and munge
# for the farm test (this writes no Slurm configuration, so the packages' own services
# stay down; the test starts its own daemons on localhost), and, when no
# `cargo` is on PATH, a stable Rust toolchain by rustup (Debian 12's own rustc 1.63 is
# too old for the dependencies), linked into /usr/local/bin so the same shell finds it.
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
    python3-openvdb       # OpenVDB 10's pyopenvdb: the .vdb reader's tests write real files
    libopenvdb-tools      # vdb_tool: re-encodes those files as zip / uncompressed
    openexr               # exrheader: the EXR test reads the headers with OpenEXR's own tool
    slurmctld             # the Slurm farm test (tests/suite/commands/slurm.rs): a one-node
    slurmd                #   cluster on localhost, started by tools/slurm-local.sh
    slurm-client          #   (sbatch, squeue, sinfo)
    munge                 #   Slurm's authentication
    ca-certificates       # rustup's download, when Rust is missing
    curl
)

if [ "$(id -u)" -eq 0 ]; then
    sudo=()
else
    sudo=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq --no-install-recommends "${packages[@]}"

if ! command -v cargo >/dev/null 2>&1; then
    echo "install-deps: no cargo on PATH; installing stable Rust with rustup" >&2
    curl --proto '=https' --tlsv1.2 -sSf https://sh.rustup.rs \
        | sh -s -- -y --profile minimal --default-toolchain stable --component clippy,rustfmt
    for tool in cargo rustc rustup; do
        "${sudo[@]}" ln -sf "$HOME/.cargo/bin/$tool" "/usr/local/bin/$tool"
    done
    cargo --version
fi

# The checks the tests run with: formatting and lints.
if command -v rustup >/dev/null 2>&1; then
    rustup component add clippy rustfmt >/dev/null
fi
