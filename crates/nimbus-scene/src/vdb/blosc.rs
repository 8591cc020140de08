//! A pure-Rust decoder for c-blosc 1.x buffers (the "Blosc" chunks in `.vdb` files).
//!
//! Layout (c-blosc `blosc.c`, format versions 1 and 2): a 16-byte header
//! `[version, codec version, flags, typesize, nbytes u32, blocksize u32, cbytes u32]`,
//! then either the raw bytes (flag `MEMCPYED`) or one `i32` start offset per block
//! followed by the blocks. A block holds `typesize` streams (one per byte of the type,
//! when the block is split) or one, each an `i32` size and that many bytes: the codec's
//! output, or the raw stream when the size equals the stream's length. A shuffled block
//! is then un-shuffled (byte `j` of element `i` sits at `j·n + i`).
//!
//! Codecs: blosclz (ported here), lz4 and lz4hc (`lz4_flex`), zlib (`flate2`). Snappy,
//! zstd and bit-shuffle are refused with an error; OpenVDB writes lz4 with byte
//! shuffle only. Every length is checked against the buffer before use, so a corrupt
//! buffer gives an error, never a panic or an over-read.

use anyhow::{bail, ensure, Result};

const HEADER: usize = 16;
const FLAG_SHUFFLE: u8 = 0x1;
const FLAG_MEMCPYED: u8 = 0x2;
const FLAG_BITSHUFFLE: u8 = 0x4;
const FLAG_FUTURE: u8 = 0x8;
const FLAG_DONT_SPLIT: u8 = 0x10;
/// c-blosc's `MAX_SPLITS` and `MIN_BUFFERSIZE`: a block is split into `typesize`
/// streams only when `typesize <= 16` and it holds at least 128 elements.
const MAX_SPLITS: usize = 16;
const MIN_BUFFERSIZE: usize = 128;

fn u32_at(src: &[u8], at: usize) -> Result<u32> {
    let bytes = src
        .get(at..at + 4)
        .ok_or_else(|| anyhow::anyhow!("blosc buffer truncated at byte {at}"))?;
    Ok(u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]))
}

fn codec_name(code: u8) -> &'static str {
    match code {
        0 => "blosclz",
        1 => "lz4",
        2 => "snappy",
        3 => "zlib",
        4 => "zstd",
        _ => "unknown",
    }
}

/// Decompresses the Blosc buffer `src`, which must hold exactly `expected` bytes.
pub fn decompress(src: &[u8], expected: usize) -> Result<Vec<u8>> {
    ensure!(
        src.len() >= HEADER,
        "blosc buffer of {} bytes is shorter than its 16-byte header",
        src.len()
    );
    let version = src[0];
    let flags = src[2];
    let typesize = usize::from(src[3]);
    let nbytes = u32_at(src, 4)? as usize;
    let blocksize = u32_at(src, 8)? as usize;
    let cbytes = u32_at(src, 12)? as usize;
    ensure!(
        version == 1 || version == 2,
        "blosc format version {version} is not supported (c-blosc 1.x writes 1 or 2)"
    );
    ensure!(
        nbytes == expected,
        "blosc buffer holds {nbytes} bytes, expected {expected}"
    );
    ensure!(
        cbytes >= HEADER && cbytes <= src.len(),
        "blosc buffer claims {cbytes} compressed bytes but has {}",
        src.len()
    );
    let src = &src[..cbytes];
    if nbytes == 0 {
        return Ok(Vec::new());
    }
    ensure!(
        flags & FLAG_FUTURE == 0,
        "blosc flags 0x{flags:02x} are from a newer format"
    );
    ensure!(typesize > 0, "blosc typesize is 0");
    if flags & FLAG_MEMCPYED != 0 {
        ensure!(
            cbytes == nbytes + HEADER,
            "stored blosc buffer has {cbytes} bytes, expected {}",
            nbytes + HEADER
        );
        return Ok(src[HEADER..].to_vec());
    }
    ensure!(
        blocksize > 0 && blocksize <= nbytes,
        "blosc block size {blocksize} is not in 1..={nbytes}"
    );
    let codec = flags >> 5;
    if !matches!(codec, 0 | 1 | 3) {
        bail!(
            "blosc codec {} is not supported (Nimbus decodes blosclz, lz4 and zlib; \
             OpenVDB writes lz4)",
            codec_name(codec)
        );
    }
    let shuffle = flags & FLAG_SHUFFLE != 0 && typesize > 1;
    let nblocks = nbytes.div_ceil(blocksize);
    ensure!(
        nblocks <= (cbytes - HEADER) / 4,
        "blosc buffer too short for its {nblocks} block offsets"
    );
    let mut out = vec![0u8; nbytes];
    let mut tmp = vec![0u8; blocksize];
    for j in 0..nblocks {
        let start = j * blocksize;
        let bsize = blocksize.min(nbytes - start);
        let leftover = bsize < blocksize;
        if !shuffle && flags & FLAG_BITSHUFFLE != 0 && bsize >= typesize {
            bail!("blosc bit-shuffle is not supported (OpenVDB uses byte shuffle)");
        }
        let offset = u32_at(src, HEADER + 4 * j)? as usize;
        let block = if shuffle {
            &mut tmp[..bsize]
        } else {
            &mut out[start..start + bsize]
        };
        decode_block(src, offset, flags, typesize, leftover, codec, block)
            .map_err(|e| anyhow::anyhow!("blosc block {j}: {e}"))?;
        if shuffle {
            unshuffle(typesize, &tmp[..bsize], &mut out[start..start + bsize]);
        }
    }
    Ok(out)
}

/// Decodes one block (its streams) starting at `offset` in `src` into `dest`.
fn decode_block(
    src: &[u8],
    mut offset: usize,
    flags: u8,
    typesize: usize,
    leftover: bool,
    codec: u8,
    dest: &mut [u8],
) -> Result<()> {
    let bsize = dest.len();
    let split = flags & FLAG_DONT_SPLIT == 0
        && typesize <= MAX_SPLITS
        && bsize / typesize >= MIN_BUFFERSIZE
        && !leftover;
    let nsplits = if split { typesize } else { 1 };
    let neblock = bsize / nsplits;
    ensure!(
        neblock * nsplits == bsize,
        "block of {bsize} bytes does not split into {nsplits} streams"
    );
    for stream in dest.chunks_exact_mut(neblock) {
        let size = u32_at(src, offset)? as i32;
        offset += 4;
        ensure!(
            size >= 0 && size as usize <= src.len() - offset,
            "stream of {size} bytes at byte {offset} runs past the buffer"
        );
        let data = &src[offset..offset + size as usize];
        offset += size as usize;
        if data.len() == neblock {
            stream.copy_from_slice(data);
            continue;
        }
        let n = match codec {
            0 => blosclz_decompress(data, stream)?,
            1 => lz4_flex::block::decompress_into(data, stream)
                .map_err(|e| anyhow::anyhow!("lz4: {e}"))?,
            _ => zlib_decompress(data, stream)?,
        };
        ensure!(
            n == neblock,
            "stream decoded to {n} bytes, expected {neblock}"
        );
    }
    Ok(())
}

/// Reverses Blosc's byte shuffle: byte `j` of element `i` is at `src[j·n + i]`, with
/// `n = len / typesize`; trailing bytes past the last whole element are copied as is.
fn unshuffle(typesize: usize, src: &[u8], dest: &mut [u8]) {
    let n = src.len() / typesize;
    for i in 0..n {
        for j in 0..typesize {
            dest[i * typesize + j] = src[j * n + i];
        }
    }
    let tail = n * typesize;
    dest[tail..].copy_from_slice(&src[tail..]);
}

/// zlib-wrapped deflate into `dest`; returns the bytes written (the stream must end).
fn zlib_decompress(data: &[u8], dest: &mut [u8]) -> Result<usize> {
    let mut z = flate2::Decompress::new(true);
    let status = z
        .decompress(data, dest, flate2::FlushDecompress::Finish)
        .map_err(|e| anyhow::anyhow!("zlib: {e}"))?;
    ensure!(
        status == flate2::Status::StreamEnd,
        "zlib stream does not end within {} bytes",
        dest.len()
    );
    Ok(z.total_out() as usize)
}

/// Maximum back-reference distance of blosclz's short form (`MAX_DISTANCE`).
const BLOSCLZ_MAX_DISTANCE: usize = 8191;

/// blosclz (a FastLZ variant), ported from c-blosc 1.21 `blosclz_decompress`.
/// Tokens: a control byte `< 32` starts a run of `ctrl + 1` literals; otherwise it is a
/// match of length `(ctrl >> 5) + 2` (extended by following bytes when the 3-bit field
/// is 7) at a distance built from its low 5 bits and the next byte (plus two more
/// bytes for far matches). As in C, the stream ends after a token when the input does.
fn blosclz_decompress(input: &[u8], out: &mut [u8]) -> Result<usize> {
    let corrupt = || anyhow::anyhow!("corrupt blosclz stream");
    let ip_limit = input.len();
    if ip_limit == 0 {
        return Ok(0);
    }
    let mut ip = 0usize;
    let mut op = 0usize;
    let mut ctrl = usize::from(input[ip] & 31);
    ip += 1;
    loop {
        if ctrl >= 32 {
            // A match: length and distance.
            let mut len = (ctrl >> 5) - 1;
            let mut ofs = (ctrl & 31) << 8;
            if len == 7 - 1 {
                loop {
                    if ip + 1 >= ip_limit {
                        return Err(corrupt());
                    }
                    let code = input[ip];
                    ip += 1;
                    len += usize::from(code);
                    if code != 255 {
                        break;
                    }
                }
            } else if ip + 1 >= ip_limit {
                return Err(corrupt());
            }
            let code = usize::from(input[ip]);
            ip += 1;
            len += 3;
            let mut back = ofs + code;
            if code == 255 && ofs == 31 << 8 {
                if ip + 1 >= ip_limit {
                    return Err(corrupt());
                }
                ofs = (usize::from(input[ip]) << 8) + usize::from(input[ip + 1]);
                ip += 2;
                back = ofs + BLOSCLZ_MAX_DISTANCE;
            }
            // The copy starts `back + 1` bytes before `op`.
            if op + len > out.len() || back + 1 > op {
                return Err(corrupt());
            }
            if ip >= ip_limit {
                break;
            }
            ctrl = usize::from(input[ip]);
            ip += 1;
            let from = op - back - 1;
            for k in 0..len {
                out[op + k] = out[from + k];
            }
            op += len;
        } else {
            // A run of literals.
            let run = ctrl + 1;
            if op + run > out.len() || ip + run > ip_limit {
                return Err(corrupt());
            }
            out[op..op + run].copy_from_slice(&input[ip..ip + run]);
            op += run;
            ip += run;
            if ip >= ip_limit {
                break;
            }
            ctrl = usize::from(input[ip]);
            ip += 1;
        }
    }
    Ok(op)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The source bytes of a vector (see tools/make_blosc_vectors.py).
    fn source(pattern: u8, nbytes: usize) -> Vec<u8> {
        if pattern == 0 {
            let n = nbytes.div_ceil(4);
            let mut v: Vec<u8> = (0..n)
                .flat_map(|i| (((i * 7) % 50) as f32 * 0.25).to_le_bytes())
                .collect();
            v.truncate(nbytes);
            v
        } else {
            let mut x: u64 = 12345;
            (0..nbytes)
                .map(|_| {
                    x = (x * 1103515245 + 12345) % (1 << 31);
                    ((x >> 16) & 0xFF) as u8
                })
                .collect()
        }
    }

    struct Vector {
        pattern: u8,
        codec: u8,
        shuffle: u8,
        typesize: u8,
        nbytes: usize,
        packed: Vec<u8>,
    }

    fn vectors() -> Vec<Vector> {
        let bytes = include_bytes!("testdata/blosc_vectors.bin");
        let mut out = Vec::new();
        let mut at = 0;
        while at < bytes.len() {
            let word = |k: usize| u32_at(bytes, at + 4 + 4 * k).unwrap() as usize;
            let len = word(2);
            out.push(Vector {
                pattern: bytes[at],
                codec: bytes[at + 1],
                shuffle: bytes[at + 2],
                typesize: bytes[at + 3],
                nbytes: word(0),
                packed: bytes[at + 16..at + 16 + len].to_vec(),
            });
            at += 16 + len;
        }
        out
    }

    #[test]
    fn c_blosc_vectors_decode_or_are_refused() {
        let all = vectors();
        assert_eq!(all.len(), 78);
        let mut decoded = 0;
        for v in &all {
            let what = format!(
                "pattern {} codec {} shuffle {} typesize {} nbytes {}",
                v.pattern, v.codec, v.shuffle, v.typesize, v.nbytes
            );
            let result = decompress(&v.packed, v.nbytes);
            if v.codec == 4 {
                let e = result.unwrap_err().to_string();
                assert!(e.contains("zstd"), "{what}: {e}");
            } else if v.shuffle == 2 {
                let e = result.unwrap_err().to_string();
                assert!(e.contains("bit-shuffle"), "{what}: {e}");
            } else {
                let got = result.unwrap_or_else(|e| panic!("{what}: {e}"));
                assert!(got == source(v.pattern, v.nbytes), "{what}: wrong bytes");
                decoded += 1;
            }
        }
        assert_eq!(decoded, 76);
    }

    #[test]
    fn vectors_cover_every_path() {
        let all = vectors();
        let flags: Vec<u8> = all.iter().map(|v| v.packed[2]).collect();
        assert!(flags.iter().any(|f| f & FLAG_MEMCPYED != 0), "memcpyed");
        assert!(flags
            .iter()
            .any(|f| f & FLAG_DONT_SPLIT == 0 && f & FLAG_MEMCPYED == 0));
        assert!(flags.iter().any(|f| f & FLAG_DONT_SPLIT != 0));
        for codec in [0u8, 1, 3] {
            assert!(flags
                .iter()
                .any(|f| f >> 5 == codec && f & FLAG_MEMCPYED == 0));
        }
        // Several blocks with a short last one.
        assert!(all
            .iter()
            .any(|v| u32_at(&v.packed, 8).unwrap() as usize * 2 < v.nbytes
                && v.nbytes % u32_at(&v.packed, 8).unwrap() as usize != 0));
    }

    #[test]
    fn corrupt_buffers_are_errors() {
        let all = vectors();
        for v in all.iter().filter(|v| v.codec != 4 && v.shuffle != 2) {
            for cut in [0, 5, 15, 16, 20, v.packed.len() / 2, v.packed.len() - 1] {
                assert!(decompress(&v.packed[..cut], v.nbytes).is_err());
            }
            for at in (0..v.packed.len()).step_by(7) {
                let mut bad = v.packed.clone();
                bad[at] ^= 0x5a;
                // Any outcome but a panic; a flip in literal bytes may still decode.
                let _ = decompress(&bad, v.nbytes);
            }
            assert!(decompress(&v.packed, v.nbytes + 1).is_err());
        }
    }

    #[test]
    fn empty_buffer_decodes_to_nothing() {
        let mut header = vec![2u8, 1, 0x21, 4];
        header.extend_from_slice(&0u32.to_le_bytes());
        header.extend_from_slice(&0u32.to_le_bytes());
        header.extend_from_slice(&16u32.to_le_bytes());
        assert!(decompress(&header, 0).unwrap().is_empty());
    }
}
