//! The brick indirection of a sparse grid: one entry per brick of the bounding box where
//! that is at most [`MAX_DENSE_CELLS`] entries (64 MiB, a box of 2048³ voxels), else
//! two-level as NanoVDB's and GVDB's trees are: a top table with one entry per node of
//! 8³ bricks (64³ lattice points), and a leaf table of 512 entries for each node that
//! holds a brick. Memory then follows the occupied nodes, not the bounding box: a grid
//! whose active voxels lie thousands of voxels apart (`assets/test-vdb/tiles_blosc.vdb`)
//! needs a few tables, where one entry per brick of its box took 3.8 GB. Grids of
//! ordinary boxes keep the one-level form: the second level's dependent load cost the
//! shaders 12 % of a frame on lavapipe.
//!
//! The entries are stored as the shaders read them (`grid_slot` in
//! `shaders/include/grid.glsl`), one `u32` array. One-level: per brick, x fastest.
//! Two-level: the top table first (x fastest), then the leaf tables; a top entry holds
//! the offset of its node's leaf table from the array's start, or [`NO_BRICK`]. An entry
//! for a brick holds its value (a storage index on the host, an atlas slot on the GPU)
//! or [`NO_BRICK`]. Offsets are relative, so arrays are concatenated into one buffer
//! without relocation; a section's offset in that buffer carries [`TWO_LEVEL`] when the
//! section is two-level ([`Indirection::tagged_offset`]).

use anyhow::{bail, Result};
use glam::IVec3;

use super::NO_BRICK;

/// Most entries of a one-level indirection: 2^24.
pub const MAX_DENSE_CELLS: u64 = 1 << 24;
/// The bit of a section's offset that says the section is two-level.
pub const TWO_LEVEL: u32 = 1 << 31;

/// Bricks along each axis of a node (a shift of 3).
pub const NODE_BRICKS: i32 = 8;
/// Entries of a leaf table.
pub const NODE_ENTRIES: usize = 512;
/// Most top-table entries: 2^24 (64 MiB), a bounding box of 2^15 lattice points along
/// every axis, or longer along some and shorter along others.
pub const MAX_TOP_CELLS: u64 = 1 << 24;

/// A brick indirection, one- or two-level (module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Indirection {
    /// Bricks per axis.
    pub dims: [u32; 3],
    /// Nodes per axis: `ceil(dims / 8)`.
    pub top_dims: [u32; 3],
    pub two_level: bool,
    /// One-level: an entry per brick. Two-level: the top table, then the leaf tables.
    pub entries: Vec<u32>,
}

/// Nodes per axis over `dims` bricks.
pub fn top_dims(dims: [u32; 3]) -> [u32; 3] {
    dims.map(|d| d.div_ceil(NODE_BRICKS as u32))
}

/// Top-table entries over `dims` bricks.
pub fn top_cells(dims: [u32; 3]) -> u64 {
    top_dims(dims).iter().map(|&d| u64::from(d)).product()
}

/// Entries of one brick per cell over `dims` bricks.
pub fn dense_cells(dims: [u32; 3]) -> u64 {
    dims.iter().map(|&d| u64::from(d)).product()
}

/// Entries of an indirection over `dims` bricks whose bricks lie in `nodes` distinct
/// nodes.
pub fn entries_for(dims: [u32; 3], nodes: u64) -> u64 {
    let dense = dense_cells(dims);
    if dense <= MAX_DENSE_CELLS {
        dense
    } else {
        top_cells(dims) + nodes * NODE_ENTRIES as u64
    }
}

impl Indirection {
    /// An empty indirection over `dims` bricks (every entry [`NO_BRICK`]): one-level up
    /// to [`MAX_DENSE_CELLS`] entries, else two-level. Refuses a top table over
    /// [`MAX_TOP_CELLS`] before allocating it.
    pub fn new(dims: [u32; 3]) -> Result<Indirection> {
        let dense = dense_cells(dims);
        if dense <= MAX_DENSE_CELLS {
            return Ok(Indirection {
                dims,
                top_dims: top_dims(dims),
                two_level: false,
                entries: vec![NO_BRICK; dense as usize],
            });
        }
        Indirection::new_two_level(dims)
    }

    /// [`Indirection::new`], two-level whatever the size (tests of the second level use
    /// it on small grids).
    pub fn new_two_level(dims: [u32; 3]) -> Result<Indirection> {
        let cells = top_cells(dims);
        if cells > MAX_TOP_CELLS {
            bail!(
                "its bounding box spans {} x {} x {} bricks of 8³ voxels ({cells} nodes of 64³ \
                 voxels), more than the {MAX_TOP_CELLS} Nimbus indexes; the active voxels \
                 are spread over too large a region",
                dims[0],
                dims[1],
                dims[2]
            );
        }
        Ok(Indirection {
            dims,
            top_dims: top_dims(dims),
            two_level: true,
            entries: vec![NO_BRICK; cells as usize],
        })
    }

    /// The offset a section of this indirection at `offset` of a concatenated buffer is
    /// read at: `offset`, with [`TWO_LEVEL`] set for a two-level one.
    pub fn tagged_offset(&self, offset: u32) -> u32 {
        if self.two_level {
            offset | TWO_LEVEL
        } else {
            offset
        }
    }

    /// Whether brick `b` lies inside `dims`.
    pub fn contains(&self, b: IVec3) -> bool {
        let d = IVec3::from_array(self.dims.map(|d| d as i32));
        b.cmpge(IVec3::ZERO).all() && b.cmplt(d).all()
    }

    fn dense_index(&self, b: IVec3) -> usize {
        let [nx, ny, _] = self.dims.map(|d| d as usize);
        (b.z as usize * ny + b.y as usize) * nx + b.x as usize
    }

    fn top_index(&self, b: IVec3) -> usize {
        let n = super::shr(b, 3).as_uvec3();
        let [tx, ty, _] = self.top_dims;
        ((n.z as usize * ty as usize) + n.y as usize) * tx as usize + n.x as usize
    }

    fn leaf_index(b: IVec3) -> usize {
        let l = (b & IVec3::splat(7)).as_uvec3();
        ((l.z * 8 + l.y) * 8 + l.x) as usize
    }

    /// The entry of brick `b`: [`NO_BRICK`] outside `dims` or where none is set.
    pub fn get(&self, b: IVec3) -> u32 {
        if !self.contains(b) {
            return NO_BRICK;
        }
        if !self.two_level {
            return self.entries[self.dense_index(b)];
        }
        let leaf = self.entries[self.top_index(b)];
        if leaf == NO_BRICK {
            return NO_BRICK;
        }
        self.entries[leaf as usize + Self::leaf_index(b)]
    }

    /// Sets the entry of brick `b` (inside `dims`), adding its node's leaf table if it
    /// has none.
    pub fn set(&mut self, b: IVec3, value: u32) -> Result<()> {
        if !self.contains(b) {
            bail!(
                "internal: brick {b} outside the indirection {:?}",
                self.dims
            );
        }
        if !self.two_level {
            let at = self.dense_index(b);
            self.entries[at] = value;
            return Ok(());
        }
        let top = self.top_index(b);
        let mut leaf = self.entries[top];
        if leaf == NO_BRICK {
            let at = self.entries.len();
            if (at + NODE_ENTRIES) as u64 >= u64::from(TWO_LEVEL) {
                bail!("internal: brick indirection of more than 2^31 entries");
            }
            self.entries.resize(at + NODE_ENTRIES, NO_BRICK);
            self.entries[top] = at as u32;
            leaf = at as u32;
        }
        self.entries[leaf as usize + Self::leaf_index(b)] = value;
        Ok(())
    }

    /// Entries held (top and leaf tables).
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether there are no entries (only a default-constructed indirection).
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn far_apart_bricks_take_a_table_each_and_read_back() {
        let dims = [1001, 763, 1313];
        let mut ind = Indirection::new(dims).unwrap();
        assert!(ind.two_level);
        assert_eq!(ind.tagged_offset(5), 5 | TWO_LEVEL);
        assert_eq!(ind.len() as u64, top_cells(dims));
        let bricks = [
            IVec3::new(0, 0, 0),
            IVec3::new(7, 7, 7),
            IVec3::new(1000, 762, 1312),
            IVec3::new(500, 3, 900),
        ];
        for (i, b) in bricks.iter().enumerate() {
            ind.set(*b, i as u32).unwrap();
        }
        // The first two share a node.
        assert_eq!(ind.len() as u64, entries_for(dims, 3));
        for (i, b) in bricks.iter().enumerate() {
            assert_eq!(ind.get(*b), i as u32);
        }
        for b in [
            IVec3::new(1, 0, 0),
            IVec3::new(8, 7, 7),
            IVec3::new(-1, 0, 0),
            IVec3::new(1001, 0, 0),
            IVec3::new(0, 0, 1313),
        ] {
            assert_eq!(ind.get(b), NO_BRICK, "{b}");
        }
        assert!(ind.set(IVec3::new(0, 763, 0), 1).is_err());
    }

    /// Ordinary boxes keep one entry per brick, x fastest, as the shaders' one-level
    /// lookup reads; both forms answer alike.
    #[test]
    fn small_boxes_are_one_level_and_both_forms_agree() {
        let dims = [20, 9, 17];
        let mut one = Indirection::new(dims).unwrap();
        let mut two = Indirection::new_two_level(dims).unwrap();
        assert!(!one.two_level && two.two_level);
        assert_eq!(one.len(), 20 * 9 * 17);
        assert_eq!(one.tagged_offset(5), 5);
        let bricks: Vec<IVec3> = (0..60)
            .map(|i| IVec3::new((i * 7) % 20, (i * 5) % 9, (i * 3) % 17))
            .collect();
        for (i, b) in bricks.iter().enumerate() {
            one.set(*b, i as u32).unwrap();
            two.set(*b, i as u32).unwrap();
        }
        let b = bricks[7];
        assert_eq!(one.entries[((b.z * 9 + b.y) * 20 + b.x) as usize], 7);
        for z in -1..18 {
            for y in -1..10 {
                for x in -1..21 {
                    let b = IVec3::new(x, y, z);
                    assert_eq!(one.get(b), two.get(b), "{b}");
                }
            }
        }
        assert_eq!(entries_for(dims, 3), 20 * 9 * 17);
    }

    #[test]
    fn a_box_too_large_is_refused_before_allocation() {
        let e = Indirection::new([1 << 17, 1 << 17, 8]).unwrap_err();
        assert!(format!("{e}").contains("more than the 16777216"), "{e}");
    }
}
