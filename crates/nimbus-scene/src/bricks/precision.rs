//! [`crate::precision::grid_effective_sigma_t`] on a sparse grid: the same rows of
//! lattice points in the 6 axis directions, but only rows through stored bricks are
//! walked, and a run of missing bricks (zeros) is one zero (after the first zero a row's
//! state no longer changes until the next non-zero value).

use std::collections::HashMap;

use glam::IVec3;

use super::{BrickGrid, BRICK_EDGE};

/// The state of one row walk (the loop body of the dense function).
struct Row {
    h: f64,
    tau: f64,
    entered: bool,
    prev: f64,
    row_max: f64,
    /// Where the row starts (for a thin row's report).
    start: IVec3,
}

impl Row {
    /// Starts a row at lattice point `at` with value `first`, `face` voxels of it
    /// between the box's face and the point.
    fn new(first: f64, face: f64, h: f64, at: IVec3, best: &mut (f64, IVec3)) -> Row {
        let tau = first * face * h;
        let entered = tau >= 1.0;
        if entered {
            consider(best, first, at);
        }
        Row {
            h,
            tau,
            entered,
            prev: first,
            row_max: first,
            start: at,
        }
    }

    /// The next lattice point `at` of the row has value `sb`.
    fn push(&mut self, sb: f64, at: IVec3, best: &mut (f64, IVec3)) {
        let (sa, h) = (self.prev, self.h);
        self.row_max = self.row_max.max(sb);
        if sa * h < 0.01 {
            self.tau = 0.0;
            self.entered = false;
        }
        let segment = 0.5 * (sa + sb) * h;
        if !self.entered && self.tau + segment >= 1.0 {
            let r = 1.0 - self.tau;
            let sigma = (sa * sa + 2.0 * (sb - sa) * r / h).max(0.0).sqrt();
            consider(best, sigma.min(sa.max(sb)), at);
            self.entered = true;
        }
        self.tau += segment;
        self.prev = sb;
    }

    fn finish(self, best: &mut (f64, IVec3)) {
        if !self.entered && self.tau < 1.0 {
            consider(best, self.row_max, self.start);
        }
    }
}

fn consider(best: &mut (f64, IVec3), sigma: f64, at: IVec3) {
    if sigma > best.0 {
        *best = (sigma, at);
    }
}

/// The largest extinction where light enters `grid` (see
/// [`crate::precision::grid_effective_sigma_t`], which this equals on a dense grid):
/// `scale` is `density_scale`, `voxel` the world length of one lattice step per axis.
/// Returns σ_eff and the primed lattice point nearest where it occurs.
pub fn effective_sigma_t(grid: &BrickGrid, scale: f64, voxel: [f64; 3]) -> (f64, IVec3) {
    let mut best = (0.0f64, grid.lattice_min);
    let value = |l: IVec3| scale * f64::from(grid.get(l));
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let h = voxel[axis];
        let (lo, hi) = (grid.lattice_min[axis], grid.lattice_max[axis]);
        // The faces' distance (in voxels) from the box to the first and last points.
        let face_lo = f64::from(lo) + 0.5 - grid.index_min[axis];
        let face_hi = grid.index_max[axis] - (f64::from(hi) + 0.5);
        // Brick columns along the axis: (brick u, brick v) -> brick coordinates along it.
        let mut columns: HashMap<(i32, i32), Vec<i32>> = HashMap::new();
        for b in &grid.bricks {
            columns.entry((b[u], b[v])).or_default().push(b[axis]);
        }
        let mut keys: Vec<(i32, i32)> = columns.keys().copied().collect();
        keys.sort_unstable();
        for key in keys {
            let Some(list) = columns.get_mut(&key) else {
                continue;
            };
            list.sort_unstable();
            for du in 0..BRICK_EDGE {
                for dv in 0..BRICK_EDGE {
                    let (lu, lv) = (key.0 * BRICK_EDGE + du, key.1 * BRICK_EDGE + dv);
                    if lu < grid.lattice_min[u]
                        || lu > grid.lattice_max[u]
                        || lv < grid.lattice_min[v]
                        || lv > grid.lattice_max[v]
                    {
                        continue;
                    }
                    let point = |m: i32| {
                        let mut l = IVec3::ZERO;
                        l[axis] = m;
                        l[u] = lu;
                        l[v] = lv;
                        l
                    };
                    for forward in [true, false] {
                        walk_row(
                            list,
                            forward,
                            (lo, hi),
                            (face_lo, face_hi),
                            h,
                            &point,
                            &value,
                            &mut best,
                        );
                    }
                }
            }
        }
    }
    best
}

/// One row (fixed `u`, `v`) through the bricks at `list` along the axis, forward or
/// backward.
#[allow(clippy::too_many_arguments)]
fn walk_row(
    list: &[i32],
    forward: bool,
    (lo, hi): (i32, i32),
    (face_lo, face_hi): (f64, f64),
    h: f64,
    point: &dyn Fn(i32) -> IVec3,
    value: &dyn Fn(IVec3) -> f64,
    best: &mut (f64, IVec3),
) {
    let start = if forward { lo } else { hi };
    let face = if forward { face_lo } else { face_hi };
    let step = if forward { 1 } else { -1 };
    let bricks: Box<dyn Iterator<Item = &i32>> = if forward {
        Box::new(list.iter())
    } else {
        Box::new(list.iter().rev())
    };
    let mut row: Option<Row> = None;
    // The next lattice point the dense walk would visit.
    let mut next = start;
    for &b in bricks {
        let (first, last) = (b * BRICK_EDGE, b * BRICK_EDGE + BRICK_EDGE - 1);
        let (a, z) = if forward {
            (first.max(lo), last.min(hi))
        } else {
            (last.min(hi), first.max(lo))
        };
        if (forward && a > z) || (!forward && a < z) {
            continue;
        }
        // Zeros before this brick: the first of them, if any.
        if next != a {
            match row.as_mut() {
                None => row = Some(Row::new(0.0, face, h, point(start), best)),
                Some(r) => r.push(0.0, point(next), best),
            }
        }
        let mut m = a;
        loop {
            let l = point(m);
            let s = value(l);
            match row.as_mut() {
                None => row = Some(Row::new(s, face, h, l, best)),
                Some(r) => r.push(s, l, best),
            }
            if m == z {
                break;
            }
            m += step;
        }
        next = z + step;
    }
    // Zeros after the last brick: the dense walk steps onto the first of them too.
    let end = if forward { hi } else { lo };
    if let Some(r) = row.as_mut() {
        if next != end + step {
            r.push(0.0, point(next), best);
        }
    }
    if let Some(r) = row {
        r.finish(best);
    }
}
