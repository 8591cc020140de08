//! Voxel grids: loading, validation, procedural cloud, trilinear lookup and the derived
//! structures (mip chain, conservative piecewise-constant grid, super-voxels).

use crate::common::{assert_contains, TempDir};
use nimbus_scene::{
    load_grid, procedural_cloud, procedural_cumulus, GridSource, ProceduralKind, VoxelGrid,
    MAX_GRID_VALUES,
};

/// A small deterministic PRNG (SplitMix64) for the property tests.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn below(&mut self, n: u32) -> u32 {
        (self.next_u64() % u64::from(n)) as u32
    }
}

fn floats_le(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn vol_bytes(dims: [i32; 3], channels: i32, values: &[f32]) -> Vec<u8> {
    let mut bytes = b"VOL".to_vec();
    bytes.push(3);
    for value in [1, dims[0], dims[1], dims[2], channels] {
        bytes.extend(value.to_le_bytes());
    }
    for value in [0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
        bytes.extend(value.to_le_bytes());
    }
    bytes.extend(floats_le(values));
    bytes
}

/// A random sparse grid: each voxel is 0 with probability `zero_fraction`.
fn random_grid(rng: &mut Rng, zero_fraction: f64) -> VoxelGrid {
    let dims = [1 + rng.below(9), 1 + rng.below(9), 1 + rng.below(9)];
    let n = dims.iter().map(|&d| d as usize).product();
    let data = (0..n)
        .map(|_| {
            if rng.unit() < zero_fraction {
                0.0
            } else {
                rng.unit() as f32 * 3.0
            }
        })
        .collect();
    VoxelGrid {
        dims,
        channels: 1,
        data,
    }
}

fn mean(values: &[f32]) -> f64 {
    values.iter().map(|&v| f64::from(v)).sum::<f64>() / values.len() as f64
}

#[test]
fn raw_round_trip() {
    let dir = TempDir::new("volume-raw");
    let dims = [3u32, 4, 5];
    let values: Vec<f32> = (0..60).map(|v| v as f32 * 0.25).collect();
    let file = dir.write("d.raw", &floats_le(&values));
    let grid = load_grid(&GridSource::Raw { file, dims }, 1, "density").unwrap();
    assert_eq!(grid.dims, dims);
    assert_eq!(grid.channels, 1);
    assert_eq!(grid.data, values);
    assert_eq!(grid.voxel_count(), 60);
    // x fastest, then y, then z.
    assert_eq!(grid.index(2, 3, 4), (4 * 4 + 3) * 3 + 2);
    assert_eq!(grid.get(1, 2, 3), values[(3 * 4 + 2) * 3 + 1]);

    // Velocity: 3 interleaved channels, negative values fine.
    let vel: Vec<f32> = (0..180).map(|v| v as f32 - 90.0).collect();
    let file = dir.write("v.raw", &floats_le(&vel));
    let grid = load_grid(&GridSource::Raw { file, dims }, 3, "velocity").unwrap();
    assert_eq!(grid.data, vel);
    assert_eq!(grid.get_channel(1, 0, 0, 2), vel[5]);
}

#[test]
fn raw_size_is_checked_again() {
    let dir = TempDir::new("volume-raw-size");
    let file = dir.write("d.raw", &floats_le(&[1.0; 7]));
    let e = load_grid(
        &GridSource::Raw {
            file,
            dims: [2, 2, 2],
        },
        1,
        "[[medium]] #1 > density",
    )
    .unwrap_err();
    assert_contains(
        &format!("{e:#}"),
        &[
            "[[medium]] #1 > density",
            "d.raw",
            "expected 32 bytes",
            "found 28",
        ],
    );
}

#[test]
fn vol_round_trip() {
    let dir = TempDir::new("volume-vol");
    let values: Vec<f32> = (0..24).map(|v| v as f32 / 7.0).collect();
    let file = dir.write("d.vol", &vol_bytes([2, 3, 4], 1, &values));
    let grid = load_grid(&GridSource::MitsubaVol { file }, 1, "density").unwrap();
    assert_eq!(grid.dims, [2, 3, 4]);
    assert_eq!(grid.data, values);

    let vel: Vec<f32> = (0..72).map(|v| -(v as f32)).collect();
    let file = dir.write("v.vol", &vol_bytes([2, 3, 4], 3, &vel));
    let grid = load_grid(
        &GridSource::MitsubaVol { file: file.clone() },
        3,
        "velocity",
    )
    .unwrap();
    assert_eq!((grid.channels, &grid.data), (3, &vel));

    // The header's channel count must match what was asked for.
    let e = load_grid(&GridSource::MitsubaVol { file }, 1, "density").unwrap_err();
    assert_contains(&format!("{e:#}"), &["v.vol", "3 channel(s), expected 1"]);
}

#[test]
fn bad_values_name_file_voxel_and_value() {
    let dir = TempDir::new("volume-bad");
    let dims = [2u32, 3, 4];
    // Voxel (1, 2, 3) is the last one: index 23.
    let cases: [(f32, u32, &str, &str); 4] = [
        (f32::NAN, 1, "NaN", "not finite"),
        (f32::INFINITY, 1, "inf", "not finite"),
        (-0.5, 1, "-0.5", "negative"),
        (f32::NEG_INFINITY, 3, "-inf", "not finite"),
    ];
    for (bad, channels, shown, problem) in cases {
        let mut values = vec![0.25f32; 24 * channels as usize];
        let last = values.len() - 1;
        values[last] = bad;
        let file = dir.write("bad.raw", &floats_le(&values));
        let e = load_grid(
            &GridSource::Raw { file, dims },
            channels,
            "[[medium]] #2 > x",
        )
        .unwrap_err();
        let message = format!("{e:#}");
        assert_contains(
            &message,
            &[
                "[[medium]] #2 > x",
                "bad.raw",
                "voxel (1, 2, 3)",
                &format!("value {shown} "),
                problem,
            ],
        );
        if channels == 3 {
            assert_contains(&message, &["channel 2"]);
        }
        // The same in a .vol file.
        let file = dir.write("bad.vol", &vol_bytes([2, 3, 4], channels as i32, &values));
        let e = load_grid(&GridSource::MitsubaVol { file }, channels, "g").unwrap_err();
        assert_contains(&format!("{e:#}"), &["bad.vol", "voxel (1, 2, 3)", shown]);
    }
    // Velocity may be negative.
    let file = dir.write("vel.raw", &floats_le(&vec![-3.0; 72]));
    assert!(load_grid(&GridSource::Raw { file, dims }, 3, "velocity").is_ok());
}

#[test]
fn memory_guard_refuses_before_reading() {
    // The files do not exist: the guard must fire first.
    let missing = std::env::temp_dir().join("nimbus-volume-missing/huge.raw");
    let cases = [
        ([4096u32, 4096, 4096], 1),
        ([2048, 1024, 1025], 1),
        ([1024, 1024, 1024], 3),
    ];
    for (dims, channels) in cases {
        let source = GridSource::Raw {
            file: missing.clone(),
            dims,
        };
        let e = load_grid(&source, channels, "[[medium]] #1 > density").unwrap_err();
        assert_contains(
            &format!("{e:#}"),
            &["[[medium]] #1 > density", "exceeds the limit", "8 GiB"],
        );
    }
    let e = load_grid(
        &GridSource::ProceduralCloud {
            dims: [4096, 4096, 4096],
            noise_seed: 1,
            kind: Default::default(),
        },
        1,
        "cloud",
    )
    .unwrap_err();
    assert_contains(&format!("{e:#}"), &["cloud", "exceeds the limit"]);
    // Exactly at the limit passes the guard (and then fails on the missing file).
    assert_eq!(MAX_GRID_VALUES, 1 << 31);
    let e = load_grid(
        &GridSource::Raw {
            file: missing,
            dims: [2048, 1024, 1024],
        },
        1,
        "d",
    )
    .unwrap_err();
    assert_contains(&format!("{e:#}"), &["not found", "huge.raw"]);
}

/// `procedural = "cumulus"` parses, loads as `procedural_cumulus` (deterministic, seeds
/// differ), and is a cumulus: densities in [0, 1], a flat base (no density below its
/// lowest filled layer's height, which is well above the floor of the box, and a wide
/// footprint there), taller than its base is wide at the top, zeros on every face.
#[test]
fn procedural_cumulus_loads_and_has_a_flat_base() {
    let scene = nimbus_scene::parse_str(
        "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[medium]]\ntype = \"grid\"\nbounds_min = [-1, -0.6, -1]\nbounds_max = [1, 0.6, 1]\n\
         density = { procedural = \"cumulus\", dims = [64, 40, 64], noise_seed = 3 }\n",
        std::path::Path::new("cumulus.toml"),
    )
    .unwrap();
    let nimbus_scene::Medium::Grid(g) = &scene.media[0] else {
        panic!("a grid medium")
    };
    let source = GridSource::ProceduralCloud {
        dims: [64, 40, 64],
        noise_seed: 3,
        kind: ProceduralKind::Cumulus,
    };
    assert_eq!(g.density, source);
    let a = load_grid(&source, 1, "cumulus").unwrap();
    let bits = |g: &VoxelGrid| g.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&procedural_cumulus([64, 40, 64], 3)));
    assert_ne!(bits(&a), bits(&procedural_cumulus([64, 40, 64], 4)));
    assert!(a.data.iter().all(|&v| (0.0..=1.0).contains(&v)));
    // Filled voxels per layer (y).
    let layer = |j: u32| {
        (0..64u32)
            .flat_map(|k| (0..64u32).map(move |i| (i, k)))
            .filter(|&(i, k)| a.get(i, j, k) > 0.0)
            .count()
    };
    let counts: Vec<usize> = (0..40).map(layer).collect();
    let base = counts.iter().position(|&n| n > 0).expect("a filled layer");
    assert!(base >= 4, "base at layer {base}: {counts:?}");
    // Flat: within two layers of the base it is already at a third of its widest.
    let widest = *counts.iter().max().unwrap();
    assert!(3 * counts[base + 2] >= widest, "{counts:?}");
    // Billowing towers: the top layers are narrower than the body.
    let top = counts.iter().rposition(|&n| n > 0).unwrap();
    assert!(top > base + 20, "{counts:?}");
    assert!(4 * counts[top - 2] < widest, "{counts:?}");
}

#[test]
fn procedural_cloud_is_deterministic_and_cloud_like() {
    let dims = [64, 64, 64];
    let a = procedural_cloud(dims, 7);
    let b = load_grid(
        &GridSource::ProceduralCloud {
            dims,
            noise_seed: 7,
            kind: Default::default(),
        },
        1,
        "cloud",
    )
    .unwrap();
    let bits = |g: &VoxelGrid| g.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b));
    let c = procedural_cloud(dims, 8);
    assert_ne!(bits(&a), bits(&c));

    for grid in [&a, &c] {
        assert!(grid.data.iter().all(|&v| (0.0..=1.0).contains(&v)));
        let nonzero = grid.data.iter().filter(|&&v| v > 0.0).count() as f64;
        let fraction = nonzero / grid.data.len() as f64;
        assert!((0.05..=0.5).contains(&fraction), "fill fraction {fraction}");
        assert!(grid.data.iter().any(|&v| v > 0.5), "some dense voxels");
        // Zeros on every face.
        for k in 0..64 {
            for j in 0..64 {
                for i in 0..64 {
                    let border = [i, j, k].iter().any(|&c| c == 0 || c == 63);
                    if border {
                        assert_eq!(grid.get(i, j, k), 0.0);
                    }
                }
            }
        }
        // Empty voxels inside the cloud: zero voxels with non-zero voxels on both
        // sides along x.
        let mut holes = 0;
        for k in 0..64 {
            for j in 0..64 {
                let row: Vec<f32> = (0..64).map(|i| grid.get(i, j, k)).collect();
                if let (Some(first), Some(last)) = (
                    row.iter().position(|&v| v > 0.0),
                    row.iter().rposition(|&v| v > 0.0),
                ) {
                    holes += row[first..last].iter().filter(|&&v| v == 0.0).count();
                }
            }
        }
        println!("interior empty voxels along x rows: {holes}");
        assert!(holes > 100, "only {holes} interior empty voxels");
    }
    // Tiny and odd sizes work.
    for dims in [[1, 1, 1], [2, 3, 1], [5, 9, 7]] {
        let g = procedural_cloud(dims, 3);
        assert_eq!(g.data.len(), g.voxel_count());
    }
}

#[test]
fn trilinear_matches_centres_and_clamps_at_faces() {
    let mut rng = Rng(11);
    for _ in 0..20 {
        let g = random_grid(&mut rng, 0.3);
        let [nx, ny, nz] = g.dims;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let c = [i, j, k].map(|v| f64::from(v) + 0.5);
                    assert_eq!(g.sample_trilinear(c), f64::from(g.get(i, j, k)));
                }
            }
        }
        // Within half a voxel of a face (and beyond) the value is the outermost centre's.
        let (j, k) = (rng.below(ny), rng.below(nz));
        let (cy, cz) = (f64::from(j) + 0.5, f64::from(k) + 0.5);
        for x in [0.0, 0.25, 0.5, -3.0] {
            assert_eq!(g.sample_trilinear([x, cy, cz]), f64::from(g.get(0, j, k)));
        }
        let n = f64::from(nx);
        for x in [n, n - 0.25, n - 0.5, n + 2.0] {
            assert_eq!(
                g.sample_trilinear([x, cy, cz]),
                f64::from(g.get(nx - 1, j, k))
            );
        }
        // Midway between two centres: the average.
        if nx >= 2 {
            let mid = g.sample_trilinear([1.0, cy, cz]);
            let expected = 0.5 * (f64::from(g.get(0, j, k)) + f64::from(g.get(1, j, k)));
            assert!((mid - expected).abs() < 1e-12);
        }
    }
}

#[test]
fn mip_chain_preserves_mean_and_handles_odd_sizes() {
    let mut rng = Rng(5);
    let data: Vec<f32> = (0..16 * 8 * 4).map(|_| rng.unit() as f32).collect();
    let g = VoxelGrid {
        dims: [16, 8, 4],
        channels: 1,
        data,
    };
    let chain = g.mip_chain();
    let dims: Vec<[u32; 3]> = chain.iter().map(|l| l.dims).collect();
    assert_eq!(
        dims,
        [[16, 8, 4], [8, 4, 2], [4, 2, 1], [2, 1, 1], [1, 1, 1]]
    );
    assert_eq!(chain[0], g);
    let m0 = mean(&g.data);
    for level in &chain {
        assert!((mean(&level.data) - m0).abs() < 1e-6, "{:?}", level.dims);
    }

    // Odd sizes: only existing children are averaged.
    let g = VoxelGrid {
        dims: [3, 1, 1],
        channels: 1,
        data: vec![1.0, 3.0, 10.0],
    };
    let chain = g.mip_chain();
    assert_eq!(chain[1].dims, [2, 1, 1]);
    assert_eq!(chain[1].data, vec![2.0, 10.0]);
    assert_eq!(chain[2].data, vec![6.0]);

    // Multi-channel grids average per channel.
    let g = VoxelGrid {
        dims: [2, 1, 1],
        channels: 3,
        data: vec![1.0, -2.0, 4.0, 3.0, 2.0, 0.0],
    };
    assert_eq!(g.mip_chain()[1].data, vec![2.0, 0.0, 2.0]);
    assert_eq!(procedural_cloud([1, 1, 1], 0).mip_chain().len(), 1);
}

/// σ* of the cell containing `p` (index space).
fn cell_value(g: &VoxelGrid, p: [f64; 3]) -> f32 {
    let c: Vec<u32> = (0..3)
        .map(|a| (p[a].floor().max(0.0) as u32).min(g.dims[a] - 1))
        .collect();
    g.get(c[0], c[1], c[2])
}

#[test]
fn conservative_grid_is_positive_wherever_trilinear_is() {
    let mut rng = Rng(99);
    let mut grids: Vec<VoxelGrid> = (0..200)
        .map(|n| random_grid(&mut rng, [0.7, 0.9, 0.97][n % 3]))
        .collect();
    grids.push(procedural_cloud([24, 20, 28], 4));
    // A single non-zero voxel: its diagonal neighbours' cells see density near corners.
    let mut lone = VoxelGrid {
        dims: [3, 3, 3],
        channels: 1,
        data: vec![0.0; 27],
    };
    lone.data[0] = 1.0;
    grids.push(lone);
    let mut checked_zero_cells = 0;
    for g in &grids {
        let cons = g.conservative_piecewise_constant();
        assert_eq!(cons.dims, g.dims);
        // Non-zero voxels keep their value (nearest).
        for (a, b) in g.data.iter().zip(&cons.data) {
            if *a != 0.0 {
                assert_eq!(a, b);
            }
        }
        let [nx, ny, nz] = g.dims;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let base = [i, j, k].map(f64::from);
                    let mut points: Vec<[f64; 3]> = (0..40)
                        .map(|_| [0, 1, 2].map(|a| base[a] + rng.unit()))
                        .collect();
                    // The cell's corners, where only the diagonal neighbour may leak in.
                    for corner in 0..8 {
                        points.push([0, 1, 2].map(|a| base[a] + f64::from((corner >> a) & 1)));
                    }
                    for p in points {
                        if g.sample_trilinear(p) > 0.0 {
                            let v = cons.get(i, j, k);
                            assert!(v > 0.0, "grid {:?}: cell ({i},{j},{k}) at {p:?}", g.dims);
                            if g.get(i, j, k) == 0.0 {
                                checked_zero_cells += 1;
                            }
                        }
                    }
                    // Also by the containing-cell lookup for interior points.
                    let p = [0, 1, 2].map(|a| base[a] + 0.01 + 0.98 * rng.unit());
                    if g.sample_trilinear(p) > 0.0 {
                        assert!(cell_value(&cons, p) > 0.0);
                    }
                }
            }
        }
    }
    assert!(checked_zero_cells > 1000, "{checked_zero_cells}");
}

#[test]
fn conservative_grid_uses_26_neighbour_average() {
    let mut g = VoxelGrid {
        dims: [3, 3, 3],
        channels: 1,
        data: vec![0.0; 27],
    };
    let corner = g.index(0, 0, 0);
    g.data[corner] = 2.6;
    let cons = g.conservative_piecewise_constant();
    // The centre voxel has 26 neighbours, one of them 2.6.
    assert!((cons.get(1, 1, 1) - 0.1).abs() < 1e-6);
    // The opposite corner has no non-zero neighbour and the trilinear field is 0 there.
    assert_eq!(cons.get(2, 2, 2), 0.0);
    assert_eq!(g.sample_trilinear([2.9, 2.9, 2.9]), 0.0);
    // Corner (1, 0, 0) has 11 in-grid neighbours.
    assert!((cons.get(1, 0, 0) - 2.6 / 11.0).abs() < 1e-6);
}

#[test]
fn super_voxels_bound_trilinear_density() {
    let mut rng = Rng(3);
    let mut grids: Vec<(VoxelGrid, u32)> = (0..30)
        .map(|n| {
            let mut g = random_grid(&mut rng, 0.5);
            // Larger grids so several super-voxels per axis exist.
            g.dims = [g.dims[0] * 3, g.dims[1] * 2, g.dims[2] * 3];
            let len = g.voxel_count();
            g.data = (0..len)
                .map(|_| {
                    if rng.unit() < 0.5 {
                        0.0
                    } else {
                        rng.unit() as f32
                    }
                })
                .collect();
            (g, [8, 4, 3][n % 3])
        })
        .collect();
    grids.push((procedural_cloud([40, 33, 24], 9), 8));
    for (g, f) in &grids {
        let sv = g.super_voxels(*f);
        assert_eq!(sv.dims, g.dims.map(|n| n.div_ceil(*f)));
        for sk in 0..sv.dims[2] {
            for sj in 0..sv.dims[1] {
                for si in 0..sv.dims[0] {
                    let s = sv.index(si, sj, sk);
                    let (lo, hi, avg) = (sv.min[s], sv.max[s], sv.avg[s]);
                    assert!(lo <= avg && avg <= hi);
                    let region: Vec<(f64, f64)> = [si, sj, sk]
                        .iter()
                        .zip(g.dims)
                        .map(|(&s, n)| (f64::from(s * f), f64::from(((s + 1) * f).min(n))))
                        .collect();
                    for _ in 0..300 {
                        let p = [0, 1, 2]
                            .map(|a| region[a].0 + (region[a].1 - region[a].0) * rng.unit());
                        let v = g.sample_trilinear(p);
                        assert!(f64::from(lo) <= v + 1e-6 && v <= f64::from(hi) + 1e-6);
                    }
                    // Region corners / faces too.
                    for corner in 0..8 {
                        let p = [0, 1, 2].map(|a| {
                            if (corner >> a) & 1 == 0 {
                                region[a].0
                            } else {
                                region[a].1
                            }
                        });
                        let v = g.sample_trilinear(p);
                        assert!(f64::from(lo) <= v + 1e-6 && v <= f64::from(hi) + 1e-6);
                    }
                }
            }
        }
    }
}

#[test]
fn super_voxel_average_is_the_exact_trilinear_mean() {
    let mut rng = Rng(17);
    let g = VoxelGrid {
        dims: [10, 7, 5],
        channels: 1,
        data: (0..350).map(|_| rng.unit() as f32).collect(),
    };
    let f = 4;
    let sv = g.super_voxels(f);
    // Midpoint quadrature on a fine grid is exact up to O(h²) for piecewise-linear
    // per-axis weights; 32 points per voxel keeps the error far below 1e-3.
    let per_voxel = 32;
    for sk in 0..sv.dims[2] {
        for sj in 0..sv.dims[1] {
            for si in 0..sv.dims[0] {
                let lo = [si, sj, sk].map(|s| s * f);
                let hi = [0, 1, 2].map(|a| (lo[a] + f).min(g.dims[a]));
                let counts = [0, 1, 2].map(|a| (hi[a] - lo[a]) * per_voxel);
                let mut sum = 0.0;
                for z in 0..counts[2] {
                    for y in 0..counts[1] {
                        for x in 0..counts[0] {
                            let idx = [x, y, z];
                            let p = [0, 1, 2].map(|a| {
                                f64::from(lo[a]) + (f64::from(idx[a]) + 0.5) / f64::from(per_voxel)
                            });
                            sum += g.sample_trilinear(p);
                        }
                    }
                }
                let mean = sum / f64::from(counts[0] * counts[1] * counts[2]);
                let avg = f64::from(sv.avg[sv.index(si, sj, sk)]);
                assert!(
                    (mean - avg).abs() < 1e-3,
                    "({si},{sj},{sk}): {mean} vs {avg}"
                );
            }
        }
    }
    // A constant grid: min = max = avg = the constant.
    let c = VoxelGrid {
        dims: [9, 9, 9],
        channels: 1,
        data: vec![0.75; 729],
    };
    let sv = c.super_voxels(8);
    assert_eq!(sv.dims, [2, 2, 2]);
    assert!(sv.min.iter().chain(&sv.max).all(|&v| v == 0.75));
    assert!(sv.avg.iter().all(|&v| (v - 0.75).abs() < 1e-6));
}
