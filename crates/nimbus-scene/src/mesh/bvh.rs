//! A bounding volume hierarchy over a triangle mesh: binned SAH on the CPU, stored
//! as a flat array of 32-byte nodes for the GPU.

use anyhow::{anyhow, bail, Result};
use glam::Vec3;

use super::{max_axis, TriangleMesh};

/// The deepest a leaf may be (the root is at depth 0). [`Bvh::build`] guarantees it.
pub const BVH_MAX_DEPTH: u32 = 32;

/// Stack entries a traversal needs that descends into the nearer child and pushes
/// the farther one (the root is not pushed): one per level below the root.
pub const BVH_STACK_SIZE: usize = BVH_MAX_DEPTH as usize;

/// Most triangles in one leaf.
pub const BVH_MAX_LEAF_TRIANGLES: u32 = 4;

/// SAH bins per axis.
const BINS: usize = 16;

/// Cost of one node visit relative to one ray–triangle test, for the SAH.
const TRAVERSAL_COST: f32 = 1.0;

/// One BVH node, 32 bytes, `#[repr(C)]` and Pod for upload as a GPU buffer (std430:
/// `struct { vec3 min; uint left_or_first; vec3 max; uint count; }`).
///
/// - Interior (`count == 0`): the children are nodes `left_or_first` and
///   `left_or_first + 1`; the node's box is the union of theirs.
/// - Leaf (`count` in 1..=[`BVH_MAX_LEAF_TRIANGLES`]): triangles `left_or_first ..
///   left_or_first + count` of [`Bvh::leaf_triangles`] / [`Bvh::triangle_ids`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BvhNode {
    pub min: [f32; 3],
    pub left_or_first: u32,
    pub max: [f32; 3],
    pub count: u32,
}

impl BvhNode {
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// A BVH over a [`TriangleMesh`], self-contained: it keeps the triangles' corners in
/// leaf order, so queries need no mesh.
///
/// Guarantees (checked by the tests): node 0 is the root; every triangle is in
/// exactly one leaf; a node's box contains its children's boxes and its triangles
/// (boxes are exact f32 min/max of the corners); leaves hold 1 to
/// [`BVH_MAX_LEAF_TRIANGLES`] triangles; no leaf is deeper than [`BVH_MAX_DEPTH`],
/// so [`BVH_STACK_SIZE`] stack entries suffice to traverse it.
///
/// GPU upload: [`Self::nodes`] (cast with bytemuck), then either
/// [`Self::leaf_triangles`] (corners, leaf order) or the mesh's indices reordered by
/// [`Self::triangle_ids`]; `triangle_ids[slot]` maps a hit back to the mesh's
/// triangle (for per-triangle data such as emission).
#[derive(Clone, Debug, PartialEq)]
pub struct Bvh {
    nodes: Vec<BvhNode>,
    triangle_ids: Vec<u32>,
    leaf_triangles: Vec<[Vec3; 3]>,
    depth: u32,
}

/// A triangle's bounds, centroid and index while building. The builder reorders
/// these in place (not indices into them), so its passes read memory in order.
#[derive(Clone, Copy)]
struct Prim {
    lo: Vec3,
    hi: Vec3,
    centroid: Vec3,
    id: u32,
}

#[derive(Clone, Copy)]
struct Bounds {
    lo: Vec3,
    hi: Vec3,
}

impl Bounds {
    const EMPTY: Self = Self {
        lo: Vec3::INFINITY,
        hi: Vec3::NEG_INFINITY,
    };

    fn grow(&mut self, lo: Vec3, hi: Vec3) {
        self.lo = self.lo.min(lo);
        self.hi = self.hi.max(hi);
    }

    /// Half the surface area (the SAH only compares ratios).
    fn half_area(&self) -> f32 {
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// Levels of halving splits needed to bring `n` triangles down to leaves:
/// ceil(log2(ceil(n / max_leaf))).
fn levels_needed(n: usize) -> u32 {
    let leaves = n.div_ceil(BVH_MAX_LEAF_TRIANGLES as usize).max(1);
    leaves.next_power_of_two().trailing_zeros()
}

struct Builder {
    /// In slot order: a node's triangles are a contiguous range.
    prims: Vec<Prim>,
    nodes: Vec<BvhNode>,
    depth: u32,
}

impl Bvh {
    /// Builds the BVH of `mesh` (which must pass [`TriangleMesh::validate`]).
    ///
    /// Binned SAH (16 bins per axis over the centroid bounds), leaves of at
    /// most [`BVH_MAX_LEAF_TRIANGLES`] triangles; a node with more must split, one
    /// with fewer splits only where the SAH says it pays. The depth bound: a node at
    /// depth d holding n triangles always keeps d + levels_needed(n) <=
    /// [`BVH_MAX_DEPTH`]; a SAH split that would break it (a very lopsided one) is
    /// replaced by a median split on the widest centroid axis, which halves n. With
    /// at most 2^26 triangles the root needs 24 levels, leaving 8 for SAH imbalance.
    pub fn build(mesh: &TriangleMesh) -> Result<Self> {
        mesh.validate().map_err(|e| anyhow!("BVH build: {e}"))?;
        let mut prims = Vec::with_capacity(mesh.indices.len());
        for i in 0..mesh.indices.len() {
            let Some([a, b, c]) = mesh.triangle(i) else {
                bail!("BVH build: triangle {i} has an index out of range");
            };
            let lo = a.min(b).min(c);
            let hi = a.max(b).max(c);
            prims.push(Prim {
                lo,
                hi,
                centroid: (lo + hi) * 0.5,
                id: i as u32,
            });
        }
        let n = prims.len();
        if levels_needed(n) > BVH_MAX_DEPTH {
            bail!("BVH build: {n} triangles need more than {BVH_MAX_DEPTH} levels");
        }
        let mut builder = Builder {
            prims,
            nodes: Vec::with_capacity(2 * n.div_ceil(2) + 1),
            depth: 0,
        };
        builder.nodes.push(BvhNode::default());
        builder.build(0, 0, n, 0);
        let Builder {
            prims,
            nodes,
            depth,
        } = builder;
        let ids: Vec<u32> = prims.iter().map(|p| p.id).collect();
        let leaf_triangles = ids
            .iter()
            .map(|&i| mesh.triangle(i as usize).unwrap_or([Vec3::ZERO; 3]))
            .collect();
        Ok(Self {
            nodes,
            triangle_ids: ids,
            leaf_triangles,
            depth,
        })
    }

    /// The nodes; node 0 is the root.
    pub fn nodes(&self) -> &[BvhNode] {
        &self.nodes
    }

    /// For each leaf slot, the index of its triangle in the mesh built from.
    pub fn triangle_ids(&self) -> &[u32] {
        &self.triangle_ids
    }

    /// For each leaf slot, its triangle's corners (in the mesh's winding).
    pub fn leaf_triangles(&self) -> &[[Vec3; 3]] {
        &self.leaf_triangles
    }

    /// The depth of the deepest leaf (0 when the root is a leaf).
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// The mesh's index triples in leaf order, for a GPU buffer leaves index into.
    pub fn reordered_indices(&self, mesh: &TriangleMesh) -> Vec<[u32; 3]> {
        self.triangle_ids
            .iter()
            .map(|&i| mesh.indices.get(i as usize).copied().unwrap_or([0; 3]))
            .collect()
    }
}

impl Builder {
    /// The triangles in slots `start..end`.
    fn slots(&self, start: usize, end: usize) -> &[Prim] {
        self.prims.get(start..end).unwrap_or(&[])
    }

    /// Fills node `node` with the triangles in slots `start..end` at `depth`.
    fn build(&mut self, node: usize, start: usize, end: usize, depth: u32) {
        let n = end - start;
        let mut bounds = Bounds::EMPTY;
        let mut centroids = Bounds::EMPTY;
        for p in self.slots(start, end) {
            bounds.grow(p.lo, p.hi);
            centroids.grow(p.centroid, p.centroid);
        }
        let make_leaf = |nodes: &mut Vec<BvhNode>| {
            if let Some(slot) = nodes.get_mut(node) {
                *slot = BvhNode {
                    min: bounds.lo.to_array(),
                    left_or_first: start as u32,
                    max: bounds.hi.to_array(),
                    count: n as u32,
                };
            }
        };
        let must_split = n > BVH_MAX_LEAF_TRIANGLES as usize;
        if !must_split && (n == 1 || depth >= BVH_MAX_DEPTH) {
            make_leaf(&mut self.nodes);
            self.depth = self.depth.max(depth);
            return;
        }

        let sah = self.best_sah_split(start, end, &bounds, &centroids);
        let leaf_cost = n as f32;
        let mid = match sah {
            Some((cost, _, _)) if !must_split && cost >= leaf_cost => None,
            None if !must_split => None,
            Some((_, axis, bin)) => {
                let mid = self.partition(start, end, axis, bin, &centroids);
                let larger = (mid - start).max(end - mid);
                if depth + 1 + levels_needed(larger) <= BVH_MAX_DEPTH {
                    Some(mid)
                } else {
                    Some(self.median_split(start, end, &centroids))
                }
            }
            None => Some(self.median_split(start, end, &centroids)),
        };
        let Some(mid) = mid else {
            make_leaf(&mut self.nodes);
            self.depth = self.depth.max(depth);
            return;
        };

        let left = self.nodes.len();
        self.nodes.push(BvhNode::default());
        self.nodes.push(BvhNode::default());
        if let Some(slot) = self.nodes.get_mut(node) {
            *slot = BvhNode {
                min: bounds.lo.to_array(),
                left_or_first: left as u32,
                max: bounds.hi.to_array(),
                count: 0,
            };
        }
        self.build(left, start, mid, depth + 1);
        self.build(left + 1, mid, end, depth + 1);
    }

    /// The bin of a centroid along `axis` (0..BINS).
    fn bin(c: f32, axis_lo: f32, scale: f32) -> usize {
        (((c - axis_lo) * scale) as usize).min(BINS - 1)
    }

    /// The cheapest binned SAH split: (cost, axis, last bin on the left), or `None`
    /// when the centroids coincide on every axis.
    fn best_sah_split(
        &self,
        start: usize,
        end: usize,
        bounds: &Bounds,
        centroids: &Bounds,
    ) -> Option<(f32, usize, usize)> {
        let extent = centroids.hi - centroids.lo;
        let scale = Vec3::splat(BINS as f32) / extent;
        let mut bins = [[(Bounds::EMPTY, 0u32); BINS]; 3];
        for p in self.slots(start, end) {
            for (axis, axis_bins) in bins.iter_mut().enumerate() {
                if extent[axis] <= 0.0 {
                    continue;
                }
                let b = Self::bin(p.centroid[axis], centroids.lo[axis], scale[axis]);
                if let Some((bounds, count)) = axis_bins.get_mut(b) {
                    bounds.grow(p.lo, p.hi);
                    *count += 1;
                }
            }
        }
        let parent_area = bounds.half_area().max(f32::MIN_POSITIVE);
        let mut best: Option<(f32, usize, usize)> = None;
        for (axis, axis_bins) in bins.iter().enumerate() {
            if extent[axis] <= 0.0 {
                continue;
            }
            // Sweep from the right: area × count of bins b+1.. for each split b.
            let mut right_cost = [0.0f32; BINS];
            let mut acc = Bounds::EMPTY;
            let mut count = 0u32;
            for b in (1..BINS).rev() {
                let (bb, c) = axis_bins[b];
                acc.grow(bb.lo, bb.hi);
                count += c;
                right_cost[b - 1] = if count > 0 {
                    acc.half_area() * count as f32
                } else {
                    f32::NAN
                };
            }
            let mut acc = Bounds::EMPTY;
            let mut count = 0u32;
            for (b, &(bb, c)) in axis_bins.iter().enumerate().take(BINS - 1) {
                acc.grow(bb.lo, bb.hi);
                count += c;
                let right = right_cost[b];
                if count == 0 || right.is_nan() {
                    continue;
                }
                let cost = TRAVERSAL_COST + (acc.half_area() * count as f32 + right) / parent_area;
                if best.is_none_or(|(best_cost, _, _)| cost < best_cost) {
                    best = Some((cost, axis, b));
                }
            }
        }
        best
    }

    /// Moves slots whose centroid bin along `axis` is <= `bin` before the others;
    /// returns the first slot of the right part.
    fn partition(
        &mut self,
        start: usize,
        end: usize,
        axis: usize,
        bin: usize,
        centroids: &Bounds,
    ) -> usize {
        let lo = centroids.lo[axis];
        let scale = BINS as f32 / (centroids.hi[axis] - lo);
        let mut i = start;
        let mut j = end;
        while i < j {
            let c = self.prims.get(i).map_or(0.0, |p| p.centroid[axis]);
            if Self::bin(c, lo, scale) <= bin {
                i += 1;
            } else {
                j -= 1;
                self.prims.swap(i, j);
            }
        }
        i
    }

    /// Splits at the median centroid along the widest centroid axis: halves n, so the
    /// depth bound always holds.
    fn median_split(&mut self, start: usize, end: usize, centroids: &Bounds) -> usize {
        let axis = max_axis(centroids.hi - centroids.lo);
        let mid = start + (end - start) / 2;
        if let Some(slots) = self.prims.get_mut(start..end) {
            slots.select_nth_unstable_by(mid - start, |a, b| {
                a.centroid[axis].total_cmp(&b.centroid[axis])
            });
        }
        mid
    }
}
