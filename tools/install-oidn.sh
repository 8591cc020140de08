#!/usr/bin/env bash
# Installs Intel Open Image Denoise 2.5.1 (CPU device, plus the CUDA device module that
# needs only the NVIDIA driver's libcuda.so.1) for the optional `oidn` cargo feature.
#
# Debian 12 does not package OIDN, and only the package registries are reachable (not
# the project's release tarballs), so the library comes from the PyPI wheel `pyoidn`,
# which ships OIDN's own prebuilt Linux libraries (manylinux2014: glibc >= 2.27,
# GLIBCXX_3.4.22 at most; Debian 12 has glibc 2.36). The wheel is pinned by version AND
# sha256; pip checks the hash (--require-hashes) and so does this script. Nothing is
# installed into Python: the wheel is only unzipped, and only the libraries are kept.
#
# Result (PREFIX defaults to /opt/oidn-2.5.1):
#   PREFIX/lib/libOpenImageDenoise.so{,.2,.2.5.1}        the C API (SONAME .so.2)
#   PREFIX/lib/libOpenImageDenoise_core.so.2.5.1          the networks and the CPU kernels
#   PREFIX/lib/libOpenImageDenoise_device_{cpu,cuda}.so.2.5.1   device modules (dlopen)
#   PREFIX/lib/libtbb.so.12{,.19}                         oneTBB, which the CPU device needs
#   PREFIX/lib/pkgconfig/OpenImageDenoise.pc              for the `oidn` crate's pkg-config probe
#   PREFIX/share/licenses/                               the wheel's licence files
# and a link /usr/local/lib/pkgconfig/OpenImageDenoise.pc -> PREFIX/lib/pkgconfig/...
# (skipped with OIDN_NO_PKGCONFIG_LINK=1; then build with OIDN_DIR=PREFIX instead).
# The libraries carry RPATH $ORIGIN/../lib, so they find each other and the bundled TBB
# without ldconfig or LD_LIBRARY_PATH; the binaries that link them get an rpath to
# PREFIX/lib from crates/nimbus-oidn/build.rs (see docs/oidn.md).
#
# Usage: tools/install-oidn.sh [PREFIX]     (root for /opt and /usr/local; idempotent)
set -euo pipefail

version=2.5.1
wheel_version=2.5.1.0
wheel=pyoidn-${wheel_version}-py3-none-manylinux2014_x86_64.whl
wheel_sha256=32ad13368f8de1ef63001942ad05b02a00cd732d1206d97f352d3a3f606d823e
prefix=${1:-/opt/oidn-${version}}

if [ "$(uname -m)" != x86_64 ] || [ "$(uname -s)" != Linux ]; then
    echo "install-oidn: only x86_64 Linux is supported (the pinned wheel is manylinux2014_x86_64)" >&2
    exit 1
fi

if [ -f "$prefix/lib/libOpenImageDenoise.so.$version" ] \
    && [ -f "$prefix/.installed-from" ] \
    && [ "$(cat "$prefix/.installed-from")" = "$wheel_sha256" ]; then
    echo "install-oidn: OIDN $version already in $prefix"
else
    if [ "$(id -u)" -eq 0 ]; then sudo=(); else sudo=(sudo); fi
    if ! python3 -m pip --version >/dev/null 2>&1; then
        export DEBIAN_FRONTEND=noninteractive
        "${sudo[@]}" apt-get install -y -qq --no-install-recommends python3-pip
    fi

    work=$(mktemp -d)
    trap 'rm -rf "$work"' EXIT
    echo "pyoidn==${wheel_version} --hash=sha256:${wheel_sha256}" >"$work/requirements.txt"
    # --platform/--python-version/--only-binary pick the one manylinux wheel whatever
    # the local Python is; --require-hashes refuses any other file.
    python3 -m pip download --quiet --no-deps --require-hashes --only-binary=:all: \
        --platform manylinux2014_x86_64 --python-version 3.11 \
        -r "$work/requirements.txt" -d "$work/dl"
    echo "${wheel_sha256}  $work/dl/${wheel}" | sha256sum --check --quiet -

    python3 - "$work/dl/$wheel" "$work/x" <<'EOF'
import sys, zipfile
wheel, dest = sys.argv[1], sys.argv[2]
keep = (
    "pyoidn/oidn/lib/libOpenImageDenoise.so.2.5.1",
    "pyoidn/oidn/lib/libOpenImageDenoise_core.so.2.5.1",
    "pyoidn/oidn/lib/libOpenImageDenoise_device_cpu.so.2.5.1",
    "pyoidn/oidn/lib/libOpenImageDenoise_device_cuda.so.2.5.1",
    "pyoidn/oidn/lib/libtbb.so.12.19",
)
with zipfile.ZipFile(wheel) as z:
    names = set(z.namelist())
    missing = [k for k in keep if k not in names]
    if missing:
        sys.exit(f"install-oidn: the wheel lacks {missing}")
    for k in keep:
        z.extract(k, dest)
    for n in names:
        if n.endswith(("/LICENSE", "/LICENSE.txt")) or "/licenses/" in n:
            z.extract(n, dest)
EOF

    staging="$prefix.new"
    "${sudo[@]}" rm -rf "$staging"
    "${sudo[@]}" mkdir -p "$staging/lib/pkgconfig" "$staging/share/licenses/pyoidn"
    "${sudo[@]}" cp "$work"/x/pyoidn/oidn/lib/*.so.* "$staging/lib/"
    "${sudo[@]}" cp -r "$work"/x/pyoidn-*.dist-info/licenses/. "$staging/share/licenses/pyoidn/"
    (
        cd "$staging/lib"
        "${sudo[@]}" ln -sf "libOpenImageDenoise.so.$version" libOpenImageDenoise.so.2
        "${sudo[@]}" ln -sf libOpenImageDenoise.so.2 libOpenImageDenoise.so
        "${sudo[@]}" ln -sf libtbb.so.12.19 libtbb.so.12
    )
    "${sudo[@]}" tee "$staging/lib/pkgconfig/OpenImageDenoise.pc" >/dev/null <<EOF
prefix=$prefix
libdir=\${prefix}/lib

Name: OpenImageDenoise
Description: Intel Open Image Denoise (from the pyoidn ${wheel_version} wheel)
Version: $version
Libs: -L\${libdir} -lOpenImageDenoise
EOF
    echo "$wheel_sha256" | "${sudo[@]}" tee "$staging/.installed-from" >/dev/null
    "${sudo[@]}" rm -rf "$prefix"
    "${sudo[@]}" mv "$staging" "$prefix"
    echo "install-oidn: installed OIDN $version into $prefix ($(du -sh "$prefix" | cut -f1))"
fi

if [ "${OIDN_NO_PKGCONFIG_LINK:-0}" != 1 ]; then
    if [ "$(id -u)" -eq 0 ]; then sudo=(); else sudo=(sudo); fi
    "${sudo[@]}" mkdir -p /usr/local/lib/pkgconfig
    "${sudo[@]}" ln -sfn "$prefix/lib/pkgconfig/OpenImageDenoise.pc" /usr/local/lib/pkgconfig/OpenImageDenoise.pc
fi

# A smoke check that the C API loads and finds its CPU device (no compiler needed).
python3 - "$prefix/lib/libOpenImageDenoise.so.2" <<'EOF'
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
lib.oidnIsCPUDeviceSupported.restype = ctypes.c_bool
if not lib.oidnIsCPUDeviceSupported():
    sys.exit("install-oidn: OIDN loaded but reports no usable CPU device (needs SSE4.1)")
print("install-oidn: OIDN loads; CPU device supported")
EOF
