#!/usr/bin/env python3
"""Writes the Blosc test vectors for Nimbus's pure-Rust Blosc decoder.

OpenVDB compresses node values with c-blosc 1.x (always the lz4 codec with byte
shuffle), and only those reach Nimbus through real .vdb files. This script covers the
decoder's other paths with buffers from the reference C library itself: every codec
Nimbus decodes (blosclz, lz4, lz4hc, zlib), no shuffle / byte shuffle, type sizes 1, 2,
4 and 12, several blocks with a short last block, and incompressible data (the
"memcpyed" flag and stored splits), plus bitshuffle and zstd buffers that the decoder
must refuse with a clear error.

Usage (one-off; the output is committed):
    python3 -m venv /tmp/blosc && /tmp/blosc/bin/pip install blosc
    /tmp/blosc/bin/python tools/make_blosc_vectors.py \
        crates/nimbus-scene/src/vdb/testdata/blosc_vectors.bin

Output: records of
    u8 pattern (0: float ramp, 1: LCG bytes), u8 codec (0 blosclz, 1 lz4, 2 lz4hc,
    3 zlib, 4 zstd), u8 shuffle (0 none, 1 byte, 2 bit), u8 typesize,
    u32 source bytes, u32 blocksize asked for (0 = automatic), u32 compressed bytes,
    then the compressed bytes; all little-endian.
The Rust test rebuilds the source bytes from (pattern, source bytes) alone.
"""
import struct
import sys

import blosc
import numpy as np

CODECS = ["blosclz", "lz4", "lz4hc", "zlib", "zstd"]
SHUFFLES = [blosc.NOSHUFFLE, blosc.SHUFFLE, blosc.BITSHUFFLE]


def source(pattern, nbytes):
    if pattern == 0:
        # A ramp of float32 values with repeats: compresses well, shuffles usefully.
        n = (nbytes + 3) // 4
        vals = np.array([float((i * 7) % 50) * 0.25 for i in range(n)], dtype="<f4")
        return vals.tobytes()[:nbytes]
    # 31-bit LCG, the high byte of each state: incompressible.
    out = bytearray()
    x = 12345
    for _ in range(nbytes):
        x = (x * 1103515245 + 12345) % (1 << 31)
        out.append((x >> 16) & 0xFF)
    return bytes(out)


def main():
    out_path = sys.argv[1]
    blosc.set_nthreads(1)
    cases = []
    for codec in range(4):
        for shuffle in range(2):
            for typesize in (1, 2, 4, 12):
                # One automatic block; small blocks with a short last block.
                cases.append((0, codec, shuffle, typesize, 2048, 0))
                cases.append((0, codec, shuffle, typesize, 5000, 1024))
        # Incompressible data, and a buffer too small to compress (memcpyed).
        cases.append((1, codec, 1, 4, 4096, 0))
        cases.append((0, codec, 1, 4, 100, 0))
        # OpenVDB's own call: typesize 4, shuffle, the whole buffer as one block.
        cases.append((0, codec, 1, 4, 2048, 2048))
    # Refused by the decoder: bitshuffle and zstd.
    cases.append((0, 1, 2, 4, 2048, 0))
    cases.append((0, 4, 1, 4, 2048, 0))

    records = bytearray()
    for pattern, codec, shuffle, typesize, nbytes, blocksize in cases:
        src = source(pattern, nbytes)
        blosc.set_blocksize(blocksize)
        packed = blosc.compress(
            src, typesize=typesize, clevel=9, shuffle=SHUFFLES[shuffle], cname=CODECS[codec]
        )
        assert blosc.decompress(packed) == src
        records += struct.pack(
            "<BBBBIII", pattern, codec, shuffle, typesize, nbytes, blocksize, len(packed)
        )
        records += packed
    with open(out_path, "wb") as f:
        f.write(records)
    print(f"{out_path}: {len(cases)} vectors, {len(records)} bytes")


if __name__ == "__main__":
    main()
