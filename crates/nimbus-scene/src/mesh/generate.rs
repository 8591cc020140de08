//! Meshes made in code, for tests, benchmarks and simple scenes.

use glam::Vec3;

use super::TriangleMesh;

impl TriangleMesh {
    /// A UV sphere with `segments` (>= 3) around the Y axis and `rings` (>= 2) from
    /// pole to pole: 2 · segments · (rings − 1) triangles, counter-clockwise seen from
    /// outside (normals point outwards). Smaller counts are raised to the minimum.
    pub fn uv_sphere(center: Vec3, radius: f32, segments: u32, rings: u32) -> Self {
        let segments = segments.max(3);
        let rings = rings.max(2);
        let mut positions = vec![center + Vec3::Y * radius];
        for r in 1..rings {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..segments {
                let phi = std::f32::consts::TAU * s as f32 / segments as f32;
                let dir = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    -theta.sin() * phi.sin(),
                );
                positions.push(center + dir * radius);
            }
        }
        let south = positions.len() as u32;
        positions.push(center - Vec3::Y * radius);
        // Vertex s of ring r (1-based ring, 0..segments).
        let at = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
        let mut indices = Vec::new();
        for s in 0..segments {
            indices.push([0, at(1, s), at(1, s + 1)]);
        }
        for r in 1..rings - 1 {
            for s in 0..segments {
                let (a, b) = (at(r, s), at(r, s + 1));
                let (c, d) = (at(r + 1, s), at(r + 1, s + 1));
                indices.push([a, c, d]);
                indices.push([a, d, b]);
            }
        }
        for s in 0..segments {
            indices.push([south, at(rings - 1, s + 1), at(rings - 1, s)]);
        }
        Self { positions, indices }
    }

    /// A height field over the square [−size/2, size/2]² in XZ with `n` × `n` quads
    /// (2n² triangles, facing +Y), displaced in Y by a deterministic sum of sines of
    /// amplitude `amplitude` with phases from `seed`: a bumpy, non-convex test mesh.
    pub fn height_field(n: u32, size: f32, amplitude: f32, seed: u64) -> Self {
        let n = n.max(1);
        // Phases from a splitmix64 of the seed.
        let mut state = seed;
        let mut phase = || {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            (z >> 40) as f32 / (1u64 << 24) as f32 * std::f32::consts::TAU
        };
        let phases = [phase(), phase(), phase(), phase()];
        let height = |x: f32, z: f32| {
            let k = std::f32::consts::TAU / size;
            amplitude
                * 0.25
                * ((3.0 * k * x + phases[0]).sin()
                    + (5.0 * k * z + phases[1]).sin()
                    + (7.0 * k * (x + z) + phases[2]).sin()
                    + (13.0 * k * (x - 0.5 * z) + phases[3]).sin())
        };
        let mut positions = Vec::with_capacity(((n + 1) * (n + 1)) as usize);
        for j in 0..=n {
            for i in 0..=n {
                let x = (i as f32 / n as f32 - 0.5) * size;
                let z = (j as f32 / n as f32 - 0.5) * size;
                positions.push(Vec3::new(x, height(x, z), z));
            }
        }
        let at = |i: u32, j: u32| j * (n + 1) + i;
        let mut indices = Vec::with_capacity(2 * (n * n) as usize);
        for j in 0..n {
            for i in 0..n {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
                // Counter-clockwise seen from +Y.
                indices.push([a, c, b]);
                indices.push([b, c, d]);
            }
        }
        Self { positions, indices }
    }

    /// An axis-aligned box from `min` to `max`: 12 triangles facing outwards. Boxes
    /// merged with [`Self::append`] make simple block letters.
    pub fn cuboid(min: Vec3, max: Vec3) -> Self {
        let corner = |k: u32| {
            Vec3::new(
                if k & 1 != 0 { max.x } else { min.x },
                if k & 2 != 0 { max.y } else { min.y },
                if k & 4 != 0 { max.z } else { min.z },
            )
        };
        let positions = (0..8).map(corner).collect();
        // Each face as a quad, counter-clockwise seen from outside.
        let quads: [[u32; 4]; 6] = [
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
        ];
        let indices = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        Self { positions, indices }
    }

    /// Adds `other`'s triangles (and vertices) to this mesh.
    pub fn append(&mut self, other: &TriangleMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.indices
            .extend(other.indices.iter().map(|t| t.map(|k| k + base)));
    }
}
