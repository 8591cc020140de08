//! The GPU mesh traversal (`shaders/include/bvh.glsl`, run by `shaders/tests/mesh_bvh.comp`)
//! against the CPU one (`nimbus_scene::Bvh::closest_hit` / `any_hit`, whose edge
//! functions are f64) on many random rays, with validation layers on. Five meshes go
//! into one scene and are uploaded as the renderer does ([`MeshBuffers`], rebased
//! indices, roots from the shape records): an axis-aligned cube, a sphere of 65 536
//! triangles, a bumpy height field, a soup of overlapping random triangles and slivers,
//! and the same cube rotated.
//!
//! Per mesh, rays of five kinds: from anywhere around the mesh (a third from inside its
//! bounds) in random directions of random length; aimed at random points of random
//! triangles; for the closed (convex) meshes, aimed exactly at vertices and edge
//! midpoints from directions that enter the solid there (the watertight test must never
//! let them through a crack); with a random `t_max`; and parallel to the axes. Each ray's closest hit and any-hit answer must agree:
//!
//! - both miss; or both hit the same triangle, the GPU's point within 1e-6 of the
//!   scene's scale (its size plus the origin's distance from 0) of that triangle's
//!   plane (measured: at most 1.6e-7; t itself is ill-conditioned along grazing rays,
//!   where one ulp of the ray's shear moves it by up to 4e-5); or both hit different
//!   triangles at a shared edge (the same point, near an edge of each); and the any-hit
//!   answer is "hit" exactly when the closest hit is;
//! - otherwise the ray passes within 1e-5 of the scale of an edge of the triangle one
//!   side hit (f32 and f64 decide an edge's side differently only that close): such rays
//!   are counted and must be fewer than 1 in 2 000 (measured: none).
//!
//! Rays aimed at vertices and edges of the closed meshes must all hit (no cracks). A
//! `t_min` just beyond the first hit finds the next surface as a brute-force scan does
//! (t within 1e-4, on every 16th ray whose next surface is not at an edge). Degenerate rays (zero, NaN or infinite direction, NaN origin) hit nothing and
//! return finite records.

use std::collections::HashMap;
use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Vec3};
use nimbus::shader_data::{shape_records, MeshBuffers};
use nimbus_gpu::BindingDesc;
use nimbus_scene::{intersect_triangle, MeshShape, Ray, Shape, ToWorld, TriangleMesh};

use crate::common::kernel::{records, Arg, Kernel};
use crate::common::rng::Pcg32;

/// FAR of constants.glsl: "no hit" and the unbounded t_max.
const FAR: f32 = 1.0e30;
const NO_INDEX: u32 = u32::MAX;
const LOCAL_SIZE: u32 = 64;
/// Rays per kind per mesh.
const RAYS: usize = 4000;
/// Relative t tolerance of the `t_min` check, whose reference is a scan of
/// `intersect_triangle` (t, not the triangle): grazing rays move t by up to 4e-5.
const T_NEXT_REL: f64 = 1e-4;
/// How far the GPU's hit point may lie from the plane of the triangle both hit,
/// relative to the scene's size plus the origin's distance from 0.
const PLANE_REL: f64 = 1e-6;
/// How close to an edge (relative to the scene's size) f32 and f64 may disagree.
const EDGE_REL: f64 = 1e-5;
/// The most such edge cases per ray.
const EDGE_FRACTION: f64 = 1.0 / 2000.0;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct MeshQuery {
    o_t_min: [f32; 4],
    d_t_max: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct MeshAnswer {
    t: f32,
    slot: u32,
    triangle: u32,
    occluded: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Push {
    query_count: u32,
    root: u32,
    node_count: u32,
    pad: u32,
}

/// A ray with its range.
#[derive(Clone, Copy, Debug)]
struct Query {
    origin: Vec3,
    dir: Vec3,
    t_min: f32,
    t_max: f32,
}

/// The scene's meshes, uploaded once, and the kernel.
struct Gpu {
    kernel: Kernel,
    buffers: MeshBuffers,
}

impl Gpu {
    fn new(buffers: MeshBuffers) -> Self {
        let layout = [
            BindingDesc::storage_buffer(0),
            BindingDesc::storage_buffer(1),
            BindingDesc::storage_buffer(nimbus::shader_data::bindings::BVH_NODES),
            BindingDesc::storage_buffer(nimbus::shader_data::bindings::MESH_TRIANGLES),
        ];
        Self {
            kernel: Kernel::new(
                nimbus::shaders::TESTS_MESH_BVH,
                &layout,
                std::mem::size_of::<Push>() as u32,
                &[],
                "mesh bvh test",
            ),
            buffers,
        }
    }

    fn run(&self, root: u32, node_count: u32, queries: &[Query]) -> Vec<MeshAnswer> {
        let gpu: Vec<MeshQuery> = queries
            .iter()
            .map(|q| MeshQuery {
                o_t_min: [q.origin.x, q.origin.y, q.origin.z, q.t_min],
                d_t_max: [q.dir.x, q.dir.y, q.dir.z, q.t_max],
            })
            .collect();
        let count = queries.len() as u32;
        let push = Push {
            query_count: count,
            root,
            node_count,
            pad: 0,
        };
        let out = self.kernel.run(
            &[
                Arg::Storage(0, bytemuck::cast_slice(&gpu)),
                Arg::Zeroed(1, queries.len() * 16),
                Arg::Storage(
                    nimbus::shader_data::bindings::BVH_NODES,
                    bytemuck::cast_slice(&self.buffers.nodes),
                ),
                Arg::Storage(
                    nimbus::shader_data::bindings::MESH_TRIANGLES,
                    bytemuck::cast_slice(&self.buffers.triangles),
                ),
            ],
            bytemuck::bytes_of(&push),
            [count.div_ceil(LOCAL_SIZE), 1, 1],
        );
        records(&out[1], queries.len())
    }
}

fn vec3(rng: &mut Pcg32, lo: Vec3, hi: Vec3) -> Vec3 {
    Vec3::new(
        rng.range(f64::from(lo.x), f64::from(hi.x)) as f32,
        rng.range(f64::from(lo.y), f64::from(hi.y)) as f32,
        rng.range(f64::from(lo.z), f64::from(hi.z)) as f32,
    )
}

fn direction(rng: &mut Pcg32) -> Vec3 {
    rng.direction().as_vec3()
}

/// A soup of `n` random triangles (a third of them slivers) in [-1, 1]³.
fn soup(n: usize, rng: &mut Pcg32) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    for i in 0..n {
        let centre = vec3(rng, Vec3::splat(-1.0), Vec3::ONE);
        let size = rng.range(0.02, 0.3) as f32;
        let a = centre + direction(rng) * size;
        let b = centre + direction(rng) * size;
        let c = if i % 3 == 0 {
            // A sliver: the third corner near the line through the first two.
            a.lerp(b, rng.range(0.1, 0.9) as f32) + direction(rng) * size * 1e-3
        } else {
            centre + direction(rng) * size
        };
        let base = mesh.positions.len() as u32;
        mesh.positions.extend([a, b, c]);
        mesh.indices.push([base, base + 1, base + 2]);
    }
    mesh
}

/// Distance from `p` to the nearest edge of triangle `t` (f64).
fn edge_distance(p: DVec3, t: [Vec3; 3]) -> f64 {
    let t = t.map(|v| v.as_dvec3());
    (0..3)
        .map(|k| {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let ab = b - a;
            let s = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
            (p - (a + s * ab)).length()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The rays of every kind for `mesh` (with its bounds), and which of them must hit
/// (aimed at vertices and edges of a closed mesh).
fn queries(mesh: &TriangleMesh, closed: bool, rng: &mut Pcg32) -> (Vec<Query>, Vec<bool>) {
    let (lo, hi) = mesh.bounds().expect("mesh has vertices");
    let centre = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5;
    let radius = half.length();
    let mut out = Vec::new();
    let mut must_hit = Vec::new();
    let unbounded = |origin, dir| Query {
        origin,
        dir,
        t_min: 0.0,
        t_max: FAR,
    };
    let outside = |rng: &mut Pcg32| centre + direction(rng) * radius * rng.range(1.2, 3.0) as f32;
    let corner = |rng: &mut Pcg32| {
        let t = rng.below(mesh.triangle_count() as u32) as usize;
        mesh.triangle(t).expect("triangle in range")
    };
    for i in 0..RAYS {
        // Anywhere around (a third inside the bounds), any direction and length.
        let origin = if i % 3 == 0 {
            vec3(rng, lo, hi)
        } else {
            vec3(rng, centre - half * 1.5, centre + half * 1.5)
        };
        let scale = rng.log_uniform(-2.0, 2.0) as f32;
        out.push(unbounded(origin, direction(rng) * scale));
        must_hit.push(false);
    }
    for _ in 0..RAYS {
        // At a random point of a random triangle.
        let [a, b, c] = corner(rng);
        let (u, v) = (rng.uniform() as f32, rng.uniform() as f32);
        let (u, v) = if u + v > 1.0 {
            (1.0 - u, 1.0 - v)
        } else {
            (u, v)
        };
        let target = a + u * (b - a) + v * (c - a);
        let origin = outside(rng);
        out.push(unbounded(origin, target - origin));
        must_hit.push(false);
    }
    if closed {
        // Exactly at a vertex or an edge midpoint of a closed convex mesh, from a
        // direction that enters the solid there (against every incident face's normal
        // by at least cos 87°): a miss would be a crack between triangles.
        let mut incident: HashMap<[u32; 2], Vec<usize>> = HashMap::new();
        for (t, tri) in mesh.indices.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                incident.entry([a.min(b), a.max(b)]).or_default().push(t);
                incident.entry([a, a]).or_default().push(t);
            }
        }
        let normal = |t: usize| {
            let [a, b, c] = mesh
                .triangle(t)
                .expect("triangle in range")
                .map(|p| p.as_dvec3());
            (b - a).cross(c - a).normalize()
        };
        let keys: Vec<[u32; 2]> = {
            let mut k: Vec<[u32; 2]> = incident.keys().copied().collect();
            k.sort_unstable();
            k
        };
        let mut made = 0;
        while made < RAYS {
            let key = keys[rng.below(keys.len() as u32) as usize];
            let faces = &incident[&key];
            let target = (mesh.positions[key[0] as usize] + mesh.positions[key[1] as usize]) * 0.5;
            let inward = -faces.iter().map(|&t| normal(t)).sum::<DVec3>().normalize();
            let d = (inward + rng.direction() * 0.2).normalize();
            if faces.iter().any(|&t| d.dot(normal(t)) > -0.05) {
                continue;
            }
            let origin = target - d.as_vec3() * 2.0 * radius;
            out.push(unbounded(origin, target - origin));
            must_hit.push(true);
            made += 1;
        }
    }
    for _ in 0..RAYS {
        // A random range end.
        let origin = vec3(rng, centre - half * 1.5, centre + half * 1.5);
        let mut q = unbounded(origin, direction(rng));
        q.t_max = rng.range(0.0, 3.0 * f64::from(radius)) as f32;
        out.push(q);
        must_hit.push(false);
    }
    for i in 0..RAYS {
        // Parallel to an axis (two zero components), either way.
        let axis = i % 3;
        let mut d = Vec3::ZERO;
        d[axis] = if i % 2 == 0 { 1.0 } else { -2.5 };
        let mut origin = vec3(rng, centre - half * 1.2, centre + half * 1.2);
        origin[axis] = centre[axis] - d[axis].signum() * 2.0 * radius;
        out.push(unbounded(origin, d));
        must_hit.push(false);
    }
    (out, must_hit)
}

#[test]
fn gpu_traversal_agrees_with_the_cpu_bvh() {
    let mut rng = Pcg32::new(0x6d65_7368);
    let rotated = {
        let mut m = TriangleMesh::cuboid(Vec3::splat(-0.7), Vec3::splat(0.7));
        let place = ToWorld {
            scale: Vec3::new(1.0, 2.0, 0.5),
            rotate_deg: Vec3::new(20.0, 35.0, -10.0),
            translate: Vec3::new(-3.0, 0.5, 1.0),
        };
        for p in &mut m.positions {
            *p = place.transform_point(*p);
        }
        m
    };
    let meshes: Vec<(&str, TriangleMesh, bool)> = vec![
        (
            "cube",
            TriangleMesh::cuboid(Vec3::splat(-0.5), Vec3::splat(0.5)),
            true,
        ),
        (
            "sphere",
            TriangleMesh::uv_sphere(Vec3::new(3.0, 0.0, 0.0), 1.5, 256, 129),
            true,
        ),
        (
            "height field",
            TriangleMesh::height_field(40, 4.0, 0.6, 7),
            false,
        ),
        ("soup", soup(3000, &mut rng), false),
        ("rotated cube", rotated, true),
    ];
    let mut scene = crate::common::gpu::scene(
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n",
        "mesh-bvh.toml",
    );
    for (name, mesh, _) in &meshes {
        let shape = MeshShape::from_mesh(name.into(), ToWorld::IDENTITY, mesh.clone()).unwrap();
        scene.shapes.push(Shape::Mesh {
            mesh: Arc::new(shape),
            albedo: Vec3::ZERO,
            emission: Vec3::ZERO,
        });
    }
    assert_eq!(shape_records(&scene).len(), meshes.len());
    let gpu = Gpu::new(MeshBuffers::build(&scene));
    let records = shape_records(&scene);
    let mut report = Vec::new();
    for (((name, mesh, closed), shape), record) in meshes.iter().zip(&scene.shapes).zip(&records) {
        let Shape::Mesh { mesh: loaded, .. } = shape else {
            unreachable!()
        };
        let bvh = &loaded.bvh;
        let root = record.p[0][0].to_bits();
        let node_count = record.p[0][3].to_bits();
        assert_eq!(node_count as usize, bvh.nodes().len());
        let (qs, must_hit) = queries(mesh, *closed, &mut rng);
        let answers = gpu.run(root, node_count, &qs);
        let (lo, hi) = mesh.bounds().unwrap();
        let size = f64::from((hi - lo).length());
        let mut edge_cases = 0usize;
        let mut max_t_rel = 0.0f64;
        let mut max_plane = 0.0f64;
        for ((q, a), must) in qs.iter().zip(&answers).zip(&must_hit) {
            let ray = Ray {
                origin: q.origin,
                dir: q.dir,
            };
            let cpu = bvh.closest_hit(&ray, q.t_max);
            let cpu_any = bvh.any_hit(&ray, q.t_max);
            assert!(a.t.is_finite(), "{name}: non-finite t for {q:?}");
            let gpu_hit = a.slot != NO_INDEX;
            assert_eq!(gpu_hit, a.t < FAR, "{name}: t and slot disagree: {a:?}");
            if *must {
                assert!(
                    gpu_hit,
                    "{name}: a ray aimed at a vertex or edge slipped through: {q:?}"
                );
            }
            let o = q.origin.as_dvec3();
            let d = q.dir.as_dvec3();
            let scale = size + o.length();
            // How far the GPU's point lies from the plane of mesh triangle `k`.
            let plane_off = |k: u32| {
                let tri = mesh.triangle(k as usize).unwrap().map(|p| p.as_dvec3());
                let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
                n.dot(o + f64::from(a.t) * d - tri[0]).abs() / scale
            };
            let near_edge = |t: f32, triangle: u32| {
                let tri = mesh.triangle(triangle as usize).unwrap();
                edge_distance(o + f64::from(t) * d, tri) <= EDGE_REL * scale
            };
            let agree = match (cpu, gpu_hit) {
                (None, false) => true,
                (Some(c), true) if c.triangle == a.triangle => {
                    // The same triangle: the GPU's point lies in its plane. (Along a
                    // grazing ray t itself is ill-conditioned: one ulp of the shear
                    // moves it by 3e-5 on the height field.)
                    let off = plane_off(c.triangle);
                    max_plane = max_plane.max(off);
                    max_t_rel = max_t_rel.max(f64::from((a.t - c.t).abs() / c.t));
                    off <= PLANE_REL
                }
                // A tie at an edge the two triangles share: the same point.
                (Some(c), true) => {
                    plane_off(c.triangle) <= PLANE_REL
                        && near_edge(c.t, c.triangle)
                        && near_edge(a.t, a.triangle)
                }
                _ => false,
            };
            if agree {
                assert_eq!(
                    a.occluded == 1,
                    gpu_hit,
                    "{name}: any-hit disagrees with closest hit for {q:?}"
                );
                assert_eq!(cpu_any, cpu.is_some(), "{name}: CPU any-hit for {q:?}");
                continue;
            }
            // Otherwise allowed only where f32 and f64 may decide an edge differently.
            let explained = cpu.is_some_and(|c| near_edge(c.t, c.triangle))
                || (gpu_hit && near_edge(a.t, a.triangle));
            assert!(
                explained,
                "{name}: GPU {a:?} but CPU {cpu:?} for {q:?}, away from any edge"
            );
            edge_cases += 1;
        }
        let fraction = edge_cases as f64 / qs.len() as f64;
        report.push(format!(
            "{name}: {} triangles, {} rays, {edge_cases} edge cases; same triangle: GPU point off \
             its plane by at most {max_plane:.1e} of the scale, t differs by at most {max_t_rel:.1e}",
            mesh.triangle_count(),
            qs.len()
        ));
        assert!(
            fraction <= EDGE_FRACTION,
            "{name}: {edge_cases} of {} rays disagree at edges",
            qs.len()
        );

        // t_min beyond the first hit: the next surface, as a brute-force scan finds it.
        let mut next = Vec::new();
        let mut expected = Vec::new();
        for q in qs.iter().step_by(16) {
            let ray = Ray {
                origin: q.origin,
                dir: q.dir,
            };
            let Some(first) = bvh.closest_hit(&ray, FAR) else {
                continue;
            };
            let t_min = first.t * 1.001;
            let beyond = (0..mesh.triangle_count())
                .filter_map(|i| intersect_triangle(&ray, mesh.triangle(i).unwrap(), FAR))
                .map(|(t, _, _)| t)
                .filter(|&t| t > t_min * 1.0001)
                .fold(FAR, f32::min);
            let at_edge = (0..mesh.triangle_count())
                .filter_map(|i| intersect_triangle(&ray, mesh.triangle(i).unwrap(), FAR))
                .any(|(t, _, _)| (t / t_min - 1.0).abs() < 2e-4);
            if at_edge {
                continue;
            }
            next.push(Query {
                t_min,
                t_max: FAR,
                ..*q
            });
            expected.push(beyond);
        }
        let answers = gpu.run(root, node_count, &next);
        let mut differ = 0;
        for ((q, a), want) in next.iter().zip(&answers).zip(&expected) {
            let same = if *want >= FAR {
                a.t >= FAR
            } else {
                f64::from((a.t - want).abs()) <= T_NEXT_REL * f64::from(*want)
            };
            if !same {
                differ += 1;
                println!(
                    "{name}: with t_min {} the GPU finds {} but a scan finds {want} for {q:?}",
                    q.t_min, a.t
                );
            }
        }
        report.push(format!(
            "{name}: t_min beyond the first hit: {} rays, {differ} differ from a scan",
            next.len()
        ));
        assert!(
            differ as f64 <= EDGE_FRACTION * next.len() as f64 + 1.0,
            "{name}: {differ} of {} rays find another next surface than a scan",
            next.len()
        );
    }
    for line in &report {
        println!("{line}");
    }

    // Degenerate rays hit nothing and stay finite.
    let nan = f32::NAN;
    let degenerate = [
        (Vec3::ZERO, Vec3::ZERO),
        (Vec3::ZERO, Vec3::new(nan, 1.0, 0.0)),
        (Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0)),
        (Vec3::new(nan, 0.0, 0.0), Vec3::X),
        (Vec3::new(0.0, f32::NEG_INFINITY, 0.0), Vec3::Y),
    ];
    let qs: Vec<Query> = degenerate
        .iter()
        .map(|&(origin, dir)| Query {
            origin,
            dir,
            t_min: 0.0,
            t_max: FAR,
        })
        .collect();
    for record in &records {
        let answers = gpu.run(record.p[0][0].to_bits(), record.p[0][3].to_bits(), &qs);
        for (q, a) in qs.iter().zip(&answers) {
            assert!(
                a.t == FAR && a.slot == NO_INDEX && a.occluded == 0,
                "degenerate ray {q:?} gave {a:?}"
            );
        }
    }
    gpu.kernel.finish();
}
