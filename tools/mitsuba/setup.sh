#!/usr/bin/env bash
# Sets up Mitsuba 3 for tools/mitsuba/compare.py (idempotent), all under target/mitsuba/:
#   venv/   python venv with mitsuba==3.9.1 (+ numpy)
#   llvm19/ Debian's libllvm19 unpacked (dpkg -x, not installed): Dr.Jit's LLVM backend
#           needs libLLVM >= 15, and Debian 12's libLLVM-15 crashes in its kernels
#           ("Cannot select: fminimum").
#   env.sh  exports DRJIT_LIBLLVM_PATH; `source target/mitsuba/env.sh` before using the venv.
# Run from the repository root: bash tools/mitsuba/setup.sh
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
dir="$root/target/mitsuba"
mkdir -p "$dir"

if [ ! -x "$dir/venv/bin/python" ]; then
  python3 -m venv "$dir/venv"
fi
if ! "$dir/venv/bin/python" -c 'import mitsuba, numpy, OpenEXR; assert mitsuba.__version__ == "3.9.1"' 2>/dev/null; then
  "$dir/venv/bin/pip" install -q --upgrade pip
  "$dir/venv/bin/pip" install -q mitsuba==3.9.1 numpy OpenEXR
fi

lib=$(ls "$dir"/llvm19/usr/lib/x86_64-linux-gnu/libLLVM.so.19* 2>/dev/null | head -1 || true)
if [ -z "$lib" ]; then
  tmp=$(mktemp -d)
  if ! (cd "$tmp" && apt-get download libllvm19 >/dev/null 2>&1); then
    apt-get update -qq
    (cd "$tmp" && apt-get download libllvm19)
  fi
  rm -rf "$dir/llvm19"
  dpkg -x "$tmp"/libllvm19_*.deb "$dir/llvm19"
  rm -rf "$tmp"
  lib=$(ls "$dir"/llvm19/usr/lib/x86_64-linux-gnu/libLLVM.so.19* | head -1)
fi
# libLLVM.so.19 needs libz3/libxml2/libedit etc.; report anything missing.
if ldd "$lib" | grep -q "not found"; then
  echo "setup.sh: $lib lacks libraries:" >&2
  ldd "$lib" | grep "not found" >&2
  echo "install them with apt-get (e.g. apt-get install -y libz3-4 libxml2 libedit2 libffi8)" >&2
  exit 1
fi

cat > "$dir/env.sh" <<EOT
export DRJIT_LIBLLVM_PATH="$lib"
EOT
echo "Mitsuba ready: source $dir/env.sh; $dir/venv/bin/python"
