//! The mesh BVH: structural invariants, the depth bound, and traversal agreeing with
//! brute force (closest hit and any hit) on random rays; the ray–triangle test on
//! its own, including watertightness at shared vertices.

use glam::Vec3;
use nimbus_scene::{
    intersect_triangle, Bvh, BvhNode, Ray, TriangleMesh, BVH_MAX_DEPTH, BVH_MAX_LEAF_TRIANGLES,
    BVH_STACK_SIZE,
};

/// splitmix64: a small deterministic generator for test data.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// A direction, sometimes axis-aligned or in a coordinate plane (zero components
    /// exercise the parallel-slab case of the box test).
    fn direction(&mut self) -> Vec3 {
        loop {
            let mut d = self.vec3(-1.0, 1.0);
            match self.below(8) {
                0 => d = Vec3::new(0.0, 0.0, d.z),
                1 => d.y = 0.0,
                _ => {}
            }
            if d.length() > 1e-3 {
                return d;
            }
        }
    }
}

/// `n` random triangles in [-1, 1]³, of very mixed sizes, a quarter of them long
/// slivers to an older vertex when `slivers`.
fn random_soup(n: usize, rng: &mut Rng, slivers: bool) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    for _ in 0..n {
        let centre = rng.vec3(-1.0, 1.0);
        let size = 0.3 * rng.f32().powi(3) + 1e-4;
        let base = mesh.positions.len() as u32;
        for _ in 0..3 {
            mesh.positions.push(centre + rng.vec3(-size, size));
        }
        let third = if slivers && base >= 3 && rng.below(4) == 0 {
            rng.below(base as usize) as u32 // reuse an older vertex: a long sliver
        } else {
            base + 2
        };
        mesh.indices.push([base, base + 1, third]);
    }
    mesh
}

#[track_caller]
fn build(mesh: &TriangleMesh) -> Bvh {
    match Bvh::build(mesh) {
        Ok(bvh) => bvh,
        Err(e) => panic!("BVH build failed: {e:#}"),
    }
}

fn contains(node: &BvhNode, lo: [f32; 3], hi: [f32; 3]) -> bool {
    (0..3).all(|k| node.min[k] <= lo[k] && hi[k] <= node.max[k])
}

/// Checks every structural guarantee of `Bvh`; returns the deepest leaf's depth.
#[track_caller]
fn check_invariants(mesh: &TriangleMesh, bvh: &Bvh) -> u32 {
    let nodes = bvh.nodes();
    let n = mesh.triangle_count();
    assert_eq!(bvh.triangle_ids().len(), n);
    assert_eq!(bvh.leaf_triangles().len(), n);
    assert!(
        nodes.len() < 2 * n,
        "{} nodes for {n} triangles",
        nodes.len()
    );
    // triangle_ids is a permutation, and leaf_triangles follows it.
    let mut seen = vec![false; n];
    for (slot, &id) in bvh.triangle_ids().iter().enumerate() {
        assert!(
            !std::mem::replace(&mut seen[id as usize], true),
            "triangle {id} twice"
        );
        assert_eq!(Some(bvh.leaf_triangles()[slot]), mesh.triangle(id as usize));
    }
    let reordered = bvh.reordered_indices(mesh);
    for (slot, &id) in bvh.triangle_ids().iter().enumerate() {
        assert_eq!(reordered[slot], mesh.indices[id as usize]);
    }
    // Walk from the root: every node reached once, every slot in exactly one leaf.
    let mut reached = vec![false; nodes.len()];
    let mut slot_leaf = vec![usize::MAX; n];
    let mut stack = vec![(0usize, 0u32)];
    let mut deepest = 0;
    while let Some((i, depth)) = stack.pop() {
        assert!(
            !std::mem::replace(&mut reached[i], true),
            "node {i} reached twice"
        );
        let node = &nodes[i];
        if node.is_leaf() {
            assert!(
                node.count <= BVH_MAX_LEAF_TRIANGLES,
                "leaf {i} has {} triangles",
                node.count
            );
            deepest = deepest.max(depth);
            let first = node.left_or_first as usize;
            let slots = first..first + node.count as usize;
            for (slot, tri) in slots.clone().zip(&bvh.leaf_triangles()[slots]) {
                assert_eq!(slot_leaf[slot], usize::MAX, "slot {slot} in two leaves");
                slot_leaf[slot] = i;
                for p in tri {
                    assert!(
                        contains(node, p.to_array(), p.to_array()),
                        "leaf {i} misses a corner {p}"
                    );
                }
            }
        } else {
            let left = node.left_or_first as usize;
            assert!(
                left > i && left + 1 < nodes.len(),
                "node {i}: children at {left}"
            );
            for child in [left, left + 1] {
                assert!(
                    contains(node, nodes[child].min, nodes[child].max),
                    "node {i} misses child {child}"
                );
                stack.push((child, depth + 1));
            }
        }
    }
    assert!(reached.iter().all(|&r| r), "unreachable nodes");
    assert!(
        slot_leaf.iter().all(|&l| l != usize::MAX),
        "a slot in no leaf"
    );
    assert!(
        deepest <= BVH_MAX_DEPTH,
        "depth {deepest} > {BVH_MAX_DEPTH}"
    );
    assert_eq!(bvh.depth(), deepest);
    deepest
}

/// Rays for a mesh: from random origins around its bounds, towards random points,
/// triangle corners and edge midpoints (shared edges), or in random directions.
fn rays(mesh: &TriangleMesh, count: usize, rng: &mut Rng) -> Vec<Ray> {
    let (lo, hi) = mesh.bounds().unwrap_or_default();
    let centre = (lo + hi) * 0.5;
    let half = (hi - lo).max(Vec3::splat(1e-3)) * 0.75;
    (0..count)
        .map(|_| {
            let origin = centre + half * rng.vec3(-1.0, 1.0) * 1.3;
            let tri = mesh
                .triangle(rng.below(mesh.triangle_count()))
                .unwrap_or_default();
            let target = match rng.below(4) {
                0 => tri[rng.below(3)],
                1 => (tri[0] + tri[1]) * 0.5,
                2 => centre + half * rng.vec3(-1.0, 1.0),
                _ => origin + rng.direction(),
            };
            let dir = if rng.below(10) == 0 {
                rng.direction()
            } else {
                target - origin
            };
            Ray { origin, dir }
        })
        .collect()
}

/// BVH queries agree with brute force on `count` rays; returns the number of hits.
///
/// One brute-force pass per ray (closest hit with no limit) gives the expected
/// answer for every limit: the closest hit below `t_max` is that hit when its t is
/// below `t_max`, and any hit below a limit exists exactly when its t is below the
/// limit (t does not depend on the limit). On small meshes the brute-force any-hit
/// is checked against that too.
#[track_caller]
fn check_agreement(mesh: &TriangleMesh, bvh: &Bvh, count: usize, rng: &mut Rng) -> usize {
    let mut hits = 0;
    let small = mesh.triangle_count() <= 10_000;
    for (k, ray) in rays(mesh, count, rng).iter().enumerate() {
        let t_max = if rng.below(3) == 0 {
            rng.range(0.0, 3.0)
        } else {
            f32::INFINITY
        };
        let closest = mesh.closest_hit_brute_force(ray, f32::INFINITY);
        let want = closest.filter(|h| h.t < t_max);
        if small {
            assert_eq!(
                want,
                mesh.closest_hit_brute_force(ray, t_max),
                "ray {k}: brute force with a limit"
            );
        }
        let got = bvh.closest_hit(ray, t_max);
        match (want, got) {
            (None, None) => {}
            (Some(w), Some(g)) => {
                hits += 1;
                // The same test on the same triangle gives the same bits: t must match
                // exactly. A different triangle is only allowed for a tie in t.
                assert_eq!(w.t, g.t, "ray {k} {ray:?}: brute {w:?}, bvh {g:?}");
                if w.triangle != g.triangle {
                    let tri = mesh.triangle(g.triangle as usize).unwrap_or_default();
                    let again = intersect_triangle(ray, tri, t_max).map(|h| h.0);
                    assert_eq!(
                        again,
                        Some(g.t),
                        "ray {k}: bvh triangle does not give its t"
                    );
                } else {
                    assert_eq!((w.u, w.v), (g.u, g.v), "ray {k}");
                }
            }
            _ => panic!("ray {k} {ray:?} t_max {t_max}: brute force {want:?}, bvh {got:?}"),
        }
        // Any hit: at the limit, exactly at the closest hit (exclusive), just above it.
        for limit in [
            t_max,
            closest.map_or(t_max, |h| h.t),
            closest.map_or(1.0, |h| h.t * 1.0001),
        ] {
            let expected = closest.is_some_and(|h| h.t < limit);
            assert_eq!(
                bvh.any_hit(ray, limit),
                expected,
                "ray {k} {ray:?}: any_hit at t_max {limit}"
            );
            if small {
                assert_eq!(
                    mesh.any_hit_brute_force(ray, limit),
                    expected,
                    "ray {k}: brute any_hit"
                );
            }
        }
    }
    hits
}

#[test]
fn node_is_32_bytes_and_pod() {
    assert_eq!(std::mem::size_of::<BvhNode>(), 32);
    assert_eq!(std::mem::align_of::<BvhNode>(), 4);
    let node = BvhNode {
        min: [1.0, 2.0, 3.0],
        left_or_first: 7,
        max: [4.0, 5.0, 6.0],
        count: 2,
    };
    let words: &[u32] = bytemuck::cast_slice(std::slice::from_ref(&node));
    assert_eq!(words[3], 7);
    assert_eq!(words[7], 2);
    assert_eq!(f32::from_bits(words[4]), 4.0);
    assert_eq!(BVH_STACK_SIZE, BVH_MAX_DEPTH as usize);
}

#[test]
fn random_soup_agrees_with_brute_force() {
    let mut rng = Rng(1);
    let mesh = random_soup(3000, &mut rng, true);
    let bvh = build(&mesh);
    check_invariants(&mesh, &bvh);
    let hits = check_agreement(&mesh, &bvh, 5000, &mut rng);
    assert!(
        hits > 1000,
        "only {hits} of 5000 rays hit: the test would prove little"
    );
}

#[test]
fn height_field_100k_agrees_with_brute_force() {
    let mesh = TriangleMesh::height_field(224, 4.0, 0.6, 3);
    assert!(mesh.triangle_count() >= 100_000);
    let bvh = build(&mesh);
    let depth = check_invariants(&mesh, &bvh);
    assert!(
        depth >= 15,
        "depth {depth} is implausibly small for 100k triangles"
    );
    let mut rng = Rng(2);
    let hits = check_agreement(&mesh, &bvh, 2000, &mut rng);
    assert!(hits > 800, "only {hits} of 2000 rays hit");
}

#[test]
fn sphere_agrees_with_brute_force_and_is_closed() {
    let mesh = TriangleMesh::uv_sphere(Vec3::new(0.5, -1.0, 2.0), 1.5, 48, 24);
    let bvh = build(&mesh);
    check_invariants(&mesh, &bvh);
    let mut rng = Rng(3);
    check_agreement(&mesh, &bvh, 2000, &mut rng);
    // From inside a closed mesh every ray hits, wherever it crosses an edge or vertex.
    for _ in 0..2000 {
        let origin = Vec3::new(0.5, -1.0, 2.0) + rng.vec3(-0.5, 0.5);
        let tri = mesh
            .triangle(rng.below(mesh.triangle_count()))
            .unwrap_or_default();
        let target = match rng.below(3) {
            0 => tri[rng.below(3)],
            1 => (tri[1] + tri[2]) * 0.5,
            _ => origin + rng.direction(),
        };
        let ray = Ray {
            origin,
            dir: target - origin,
        };
        assert!(
            bvh.closest_hit(&ray, f32::INFINITY).is_some(),
            "ray {ray:?} escaped the sphere"
        );
    }
}

#[test]
fn rays_through_shared_vertices_and_edges_never_slip_through() {
    // Watertightness: rays aimed exactly at interior vertices and edge midpoints of a
    // bumpy surface must hit it. The surface's slope stays below 1.2 (amplitude 0.05)
    // and the rays come from above within 0.2 × their drop horizontally, so every
    // triangle faces them and they stay above the surface until the target: a miss
    // can only be a crack.
    let n = 40;
    let mesh = TriangleMesh::height_field(n, 2.0, 0.05, 9);
    let bvh = build(&mesh);
    let mut rng = Rng(4);
    let row = n as usize + 1;
    for k in 0..4000 {
        let (i, j) = (1 + rng.below(row - 2), 1 + rng.below(row - 2));
        let vertex = mesh.positions[j * row + i];
        let neighbour = mesh.positions[j * row + i + 1];
        let diagonal = mesh.positions[(j + 1) * row + i - 1];
        let target = match k % 3 {
            0 => vertex,
            1 => (vertex + neighbour) * 0.5,
            _ => (vertex + diagonal) * 0.5,
        };
        let drop = rng.range(0.5, 2.0);
        let offset = Vec3::new(rng.range(-0.2, 0.2), 1.0, rng.range(-0.2, 0.2)) * drop;
        let ray = Ray {
            origin: target + offset,
            dir: -offset,
        };
        assert!(
            mesh.closest_hit_brute_force(&ray, f32::INFINITY).is_some(),
            "ray {k} {ray:?} slipped through at {target}"
        );
        assert!(bvh.any_hit(&ray, 2.0), "ray {k}: any_hit missed");
    }
}

#[test]
fn depth_bound_holds_where_sah_alone_would_not() {
    // Triangles spaced geometrically along x: each binned SAH split peels off only
    // the last few, which without the bound makes a tree hundreds of levels deep.
    let mut mesh = TriangleMesh::default();
    for i in 0..3000u32 {
        let x = 1.01f32.powi(i as i32);
        let base = mesh.positions.len() as u32;
        let s = 1e-3 * x;
        mesh.positions.extend([
            Vec3::new(x, 0.0, 0.0),
            Vec3::new(x + s, 0.0, 0.0),
            Vec3::new(x, s, s),
        ]);
        mesh.indices.push([base, base + 1, base + 2]);
    }
    let bvh = build(&mesh);
    let depth = check_invariants(&mesh, &bvh);
    assert!(depth <= BVH_MAX_DEPTH);
    assert!(
        depth > 20,
        "depth {depth}: the SAH is no longer lopsided here, the test proves nothing"
    );
    let mut rng = Rng(5);
    check_agreement(&mesh, &bvh, 500, &mut rng);
}

#[test]
fn coincident_triangles_and_tiny_meshes() {
    // 1000 copies of one triangle: no SAH split exists, median splits must do.
    let mut mesh = TriangleMesh::default();
    for _ in 0..1000 {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend([Vec3::ZERO, Vec3::X, Vec3::Y]);
        mesh.indices.push([base, base + 1, base + 2]);
    }
    let bvh = build(&mesh);
    check_invariants(&mesh, &bvh);
    let ray = Ray {
        origin: Vec3::new(0.25, 0.25, 1.0),
        dir: Vec3::NEG_Z,
    };
    let hit = bvh.closest_hit(&ray, f32::INFINITY);
    assert_eq!(hit.map(|h| h.t), Some(1.0));

    // One triangle: the root is a leaf.
    let one = TriangleMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        indices: vec![[0, 1, 2]],
    };
    let bvh = build(&one);
    assert_eq!(bvh.nodes().len(), 1);
    assert_eq!(check_invariants(&one, &bvh), 0);
    assert!(bvh.any_hit(&ray, 2.0));
    assert!(!bvh.any_hit(&ray, 1.0), "t_max is exclusive");
    assert!(!bvh.any_hit(
        &Ray {
            origin: ray.origin,
            dir: Vec3::Z
        },
        f32::INFINITY
    ));

    // Invalid meshes are refused, not built.
    assert!(Bvh::build(&TriangleMesh::default()).is_err());
    let bad = TriangleMesh {
        positions: vec![Vec3::ZERO, Vec3::X],
        indices: vec![[0, 1, 2]],
    };
    assert!(Bvh::build(&bad).is_err());
    let nan = TriangleMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::NAN],
        indices: vec![[0, 1, 2]],
    };
    assert!(Bvh::build(&nan).is_err());
}

#[test]
fn triangle_test_basics() {
    let tri = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
    ];
    let ray = Ray {
        origin: Vec3::new(0.5, 0.25, 3.0),
        dir: Vec3::new(0.0, 0.0, -2.0),
    };
    let (t, u, v) = intersect_triangle(&ray, tri, f32::INFINITY).unwrap_or_default();
    assert!((t - 1.5).abs() < 1e-6, "t = {t}");
    let point = (1.0 - u - v) * tri[0] + u * tri[1] + v * tri[2];
    assert!(point.abs_diff_eq(ray.origin + t * ray.dir, 1e-6), "{point}");
    assert!(
        (u - 0.25).abs() < 1e-6 && (v - 0.125).abs() < 1e-6,
        "u {u} v {v}"
    );
    // Both sides hit, ranges are exclusive, behind the origin is no hit.
    let below = Ray {
        origin: Vec3::new(0.5, 0.25, -1.0),
        dir: Vec3::Z,
    };
    assert!(intersect_triangle(&below, tri, f32::INFINITY).is_some());
    assert!(intersect_triangle(&ray, tri, 1.5).is_none());
    assert!(intersect_triangle(&ray, tri, 1.5001).is_some());
    let away = Ray {
        origin: ray.origin,
        dir: Vec3::Z,
    };
    assert!(intersect_triangle(&away, tri, f32::INFINITY).is_none());
    // Parallel to the plane, outside, zero direction, degenerate triangle: no hit.
    let parallel = Ray {
        origin: Vec3::new(-1.0, 0.5, 0.0),
        dir: Vec3::X,
    };
    assert!(intersect_triangle(&parallel, tri, f32::INFINITY).is_none());
    let outside = Ray {
        origin: Vec3::new(1.5, 1.5, 1.0),
        dir: Vec3::NEG_Z,
    };
    assert!(intersect_triangle(&outside, tri, f32::INFINITY).is_none());
    assert!(intersect_triangle(
        &Ray {
            origin: ray.origin,
            dir: Vec3::ZERO
        },
        tri,
        f32::INFINITY
    )
    .is_none());
    let flat = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
    let at_line = Ray {
        origin: Vec3::new(0.5, 0.0, 1.0),
        dir: Vec3::NEG_Z,
    };
    assert!(intersect_triangle(&at_line, flat, f32::INFINITY).is_none());
    // Exactly on an edge and exactly through a vertex: hit.
    let edge = Ray {
        origin: Vec3::new(1.0, 0.0, 1.0),
        dir: Vec3::NEG_Z,
    };
    assert!(intersect_triangle(&edge, tri, f32::INFINITY).is_some());
    let corner = Ray {
        origin: Vec3::new(2.0, 0.0, 1.0),
        dir: Vec3::NEG_Z,
    };
    assert!(intersect_triangle(&corner, tri, f32::INFINITY).is_some());
}

/// Seconds this thread has run on a CPU (Linux: /proc/thread-self/schedstat), so
/// timings on a shared, loaded machine count only our own work; `None` elsewhere.
fn thread_cpu_seconds() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

/// Wall and CPU seconds of `f`.
fn timed<T>(f: impl FnOnce() -> T) -> (T, f64, Option<f64>) {
    let cpu = thread_cpu_seconds();
    let wall = std::time::Instant::now();
    let value = f();
    let wall = wall.elapsed().as_secs_f64();
    let cpu = cpu.zip(thread_cpu_seconds()).map(|(a, b)| b - a);
    (value, wall, cpu)
}

/// Build times for the final report: `cargo test --release -p nimbus-scene --test
/// mesh_bvh -- --ignored --nocapture build_times` (one thread).
#[test]
#[ignore = "timing, run in release by hand"]
fn build_times() {
    let meshes = [
        (
            "height field 100k",
            TriangleMesh::height_field(224, 4.0, 0.6, 3),
        ),
        (
            "uv sphere 100k",
            TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 317, 159),
        ),
        (
            "height field 1M",
            TriangleMesh::height_field(708, 4.0, 0.6, 3),
        ),
        (
            "uv sphere 1M",
            TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 1000, 501),
        ),
        ("random soup 1M", random_soup(1_000_000, &mut Rng(6), false)),
        // A quarter are slivers across the cube: every box overlaps every ray, the
        // worst case for a BVH without spatial splits.
        (
            "random soup with slivers 100k",
            random_soup(100_000, &mut Rng(6), true),
        ),
    ];
    let show = |cpu: Option<f64>| cpu.map_or("?".to_string(), |c| format!("{c:.3}"));
    for (name, mesh) in &meshes {
        let (bvh, build_wall, build_cpu) = timed(|| build(mesh));
        let rays = rays(mesh, 100_000, &mut Rng(7));
        let (hits, trace_wall, trace_cpu) = timed(|| {
            rays.iter()
                .filter(|r| bvh.closest_hit(r, f32::INFINITY).is_some())
                .count()
        });
        println!(
            "{name}: {} triangles, build {build_wall:.3} s wall / {} s CPU, {} nodes, depth {}; \
             100k closest-hit rays {trace_wall:.3} s wall / {} s CPU ({hits} hits)",
            mesh.triangle_count(),
            show(build_cpu),
            bvh.nodes().len(),
            bvh.depth(),
            show(trace_cpu),
        );
    }
}
