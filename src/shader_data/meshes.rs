//! The scene's triangle meshes as the shaders read them (`bvh.glsl`): every mesh's BVH
//! nodes in one buffer and its leaf triangles in another, concatenated in shape order.
//! Indices inside each BVH are rebased on the way, so the shaders follow absolute
//! indices; a mesh's [`ShapeGpu`](super::ShapeGpu) record names its root node (see
//! [`super::scene::shape_records`], which places the meshes in the same order).

use nimbus_scene::{BvhNode, Scene, Shape};

use super::records::MeshTriangleGpu;

/// Bytes of one BVH node on the GPU.
pub const BVH_NODE_BYTES: u64 = std::mem::size_of::<BvhNode>() as u64;
/// Bytes of one mesh triangle on the GPU.
pub const MESH_TRIANGLE_BYTES: u64 = std::mem::size_of::<MeshTriangleGpu>() as u64;

/// The node and triangle buffers of a scene's meshes. Storage buffers cannot be empty:
/// a scene without meshes gets one zeroed record in each (never read: the traversal
/// is compiled out).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshBuffers {
    pub nodes: Vec<BvhNode>,
    pub triangles: Vec<MeshTriangleGpu>,
    /// Meshes in the scene.
    pub meshes: usize,
}

/// The number of BVH nodes and triangles of all of `scene`'s meshes.
pub fn mesh_counts(scene: &Scene) -> (u64, u64) {
    scene
        .shapes
        .iter()
        .fold((0, 0), |(nodes, triangles), shape| match shape {
            Shape::Mesh { mesh, .. } => (
                nodes + mesh.bvh.nodes().len() as u64,
                triangles + mesh.triangle_count() as u64,
            ),
            _ => (nodes, triangles),
        })
}

impl MeshBuffers {
    /// Concatenates the BVHs of `scene`'s meshes in shape order, rebasing each node's
    /// child or triangle index by where its mesh starts.
    pub fn build(scene: &Scene) -> MeshBuffers {
        let (node_count, triangle_count) = mesh_counts(scene);
        let mut out = MeshBuffers {
            nodes: Vec::with_capacity(node_count as usize),
            triangles: Vec::with_capacity(triangle_count as usize),
            meshes: 0,
        };
        for shape in &scene.shapes {
            let Shape::Mesh { mesh, .. } = shape else {
                continue;
            };
            out.meshes += 1;
            let node_base = out.nodes.len() as u32;
            let triangle_base = out.triangles.len() as u32;
            out.nodes.extend(mesh.bvh.nodes().iter().map(|n| BvhNode {
                left_or_first: n.left_or_first
                    + if n.is_leaf() {
                        triangle_base
                    } else {
                        node_base
                    },
                ..*n
            }));
            let bvh = &mesh.bvh;
            out.triangles
                .extend(
                    bvh.leaf_triangles()
                        .iter()
                        .zip(bvh.triangle_ids())
                        .map(|(p, &id)| MeshTriangleGpu {
                            p0: p[0].to_array(),
                            triangle: id,
                            p1: p[1].to_array(),
                            _pad0: 0,
                            p2: p[2].to_array(),
                            _pad1: 0,
                        }),
                );
        }
        if out.nodes.is_empty() {
            out.nodes.push(BvhNode::default());
        }
        if out.triangles.is_empty() {
            out.triangles.push(MeshTriangleGpu::default());
        }
        out
    }
}
