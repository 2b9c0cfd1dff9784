//! Macrocells: a coarse grid over a spatial field holding the range of values each block of the
//! field can take, built when the field is committed. A volume maps each range through its
//! transfer function to learn which blocks are empty, and ray marching skips their stretch of
//! the ray, and how opaque the others can be, to step through them in proportion (see
//! [`MacrocellGrid::classified_spans`]).

use glam::Vec3;

/// Grid cells per macrocell side for structured fields.
pub(crate) const CELLS_PER_MACROCELL: usize = 8;
/// Most macrocells along one axis.
const MAX_MACROCELLS_PER_AXIS: usize = 64;

/// A block's value range; `EMPTY` where the field has no value (NaN everywhere or no cell).
pub type ValueRange = (f32, f32);
pub const EMPTY: ValueRange = (f32::INFINITY, f32::NEG_INFINITY);

/// Value ranges over a uniform grid of boxes `origin + index × size`.
#[derive(Debug)]
pub struct MacrocellGrid {
    origin: Vec3,
    size: Vec3,
    dims: [usize; 3],
    ranges: Vec<ValueRange>,
}

fn widen((lo, hi): ValueRange, value: f32) -> ValueRange {
    // NaN values are empty space for volumes; they widen nothing.
    if value.is_nan() {
        (lo, hi)
    } else {
        (lo.min(value), hi.max(value))
    }
}

impl MacrocellGrid {
    /// Macrocells of `CELLS_PER_MACROCELL`³ cells over a vertex-centred grid of `dims` vertices
    /// placed at `origin` with `spacing`; `vertex(i, j, k)` reads a vertex value. Each block
    /// includes the vertices on its far faces: trilinear and nearest reconstruction inside a
    /// block read only those.
    pub fn over_grid(
        dims: [usize; 3],
        origin: Vec3,
        spacing: Vec3,
        vertex: impl Fn([usize; 3]) -> f32,
    ) -> MacrocellGrid {
        let blocks = dims.map(|n| n.saturating_sub(1).div_ceil(CELLS_PER_MACROCELL).max(1));
        let mut ranges = vec![EMPTY; blocks[0] * blocks[1] * blocks[2]];
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let value = vertex([i, j, k]);
                    if value.is_nan() {
                        continue;
                    }
                    // A vertex on a block boundary belongs to the blocks on both sides.
                    let owners = |v: usize, n: usize| {
                        let hi = (v / CELLS_PER_MACROCELL).min(n - 1);
                        let lo = if v.is_multiple_of(CELLS_PER_MACROCELL) && v > 0 {
                            hi.min(v / CELLS_PER_MACROCELL - 1)
                        } else {
                            hi
                        };
                        lo..=hi
                    };
                    for bz in owners(k, blocks[2]) {
                        for by in owners(j, blocks[1]) {
                            for bx in owners(i, blocks[0]) {
                                let index = bx + blocks[0] * (by + blocks[1] * bz);
                                ranges[index] = widen(ranges[index], value);
                            }
                        }
                    }
                }
            }
        }
        let size = (spacing * CELLS_PER_MACROCELL as f32).max(Vec3::splat(f32::MIN_POSITIVE));
        MacrocellGrid {
            origin,
            size,
            dims: blocks,
            ranges,
        }
    }

    /// Macrocells over the box `bounds` for cells given as (box, value range): every block a
    /// cell's box touches takes its range. About one block per cell, 8 to 64 along the box's
    /// longest side.
    pub fn over_cells(
        bounds: (Vec3, Vec3),
        cells: impl Iterator<Item = ((Vec3, Vec3), ValueRange)>,
        cell_count: usize,
    ) -> MacrocellGrid {
        let (lo, hi) = bounds;
        let extent = (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE));
        let per_axis = (cell_count as f32)
            .cbrt()
            .clamp(8.0, MAX_MACROCELLS_PER_AXIS as f32);
        // Blocks roughly cubic: proportional to the box's sides, the longest getting per_axis.
        let longest = extent.max_element();
        let dims = [0, 1, 2].map(|a| {
            ((per_axis * extent[a] / longest).ceil() as usize).clamp(1, MAX_MACROCELLS_PER_AXIS)
        });
        let size = extent / Vec3::new(dims[0] as f32, dims[1] as f32, dims[2] as f32);
        let mut grid = MacrocellGrid {
            origin: lo,
            size,
            dims,
            ranges: vec![EMPTY; dims[0] * dims[1] * dims[2]],
        };
        // A hair around each block, so a point on a face finds the cells of both sides.
        let margin = size * 1e-3;
        for ((cell_lo, cell_hi), (vmin, vmax)) in cells {
            let first = grid.block_of(cell_lo - margin);
            let last = grid.block_of(cell_hi + margin);
            for bz in first[2]..=last[2] {
                for by in first[1]..=last[1] {
                    for bx in first[0]..=last[0] {
                        let index = bx + dims[0] * (by + dims[1] * bz);
                        let range = widen(grid.ranges[index], vmin);
                        grid.ranges[index] = widen(range, vmax);
                    }
                }
            }
        }
        grid
    }

    /// The block holding `point`, clamped into the grid.
    fn block_of(&self, point: Vec3) -> [usize; 3] {
        let local = (point - self.origin) / self.size;
        [0, 1, 2].map(|a| {
            let v = local[a].floor();
            if v.is_nan() || v < 0.0 {
                0
            } else {
                (v as usize).min(self.dims[a] - 1)
            }
        })
    }

    pub fn ranges(&self) -> &[ValueRange] {
        &self.ranges
    }

    /// Stretches of `origin + t × direction` (object space), `t` in [`t0`, `t1`], that cross
    /// blocks whose `class` is not 0 (empty), each with that class: consecutive blocks of one
    /// class make one stretch. A run of non-empty blocks is widened by a thousandth of a block
    /// at both ends, so that a point on a face between an empty and a non-empty block counts as
    /// inside both; where two non-empty classes meet, the smaller class takes that margin.
    /// Sorted and disjoint. Blocks are visited in ray order (a 3D DDA).
    pub fn classified_spans(
        &self,
        class: impl Fn(usize) -> u32,
        origin: Vec3,
        direction: Vec3,
        (t0, t1): (f32, f32),
        spans: &mut Vec<(f32, f32, u32)>,
    ) {
        spans.clear();
        if t0 >= t1 {
            return;
        }
        let inverse = direction.recip();
        let pad = self.size.min_element() * 1e-3 / direction.length();
        let start = origin + direction * t0;
        let mut block = self.block_of(start);
        let mut step = [0isize; 3];
        let mut t_next = [f32::INFINITY; 3];
        let mut t_delta = [f32::INFINITY; 3];
        for a in 0..3 {
            if direction[a] == 0.0 || !inverse[a].is_finite() {
                continue;
            }
            let forward = direction[a] > 0.0;
            step[a] = if forward { 1 } else { -1 };
            let boundary =
                self.origin[a] + self.size[a] * (block[a] as f32 + if forward { 1.0 } else { 0.0 });
            t_next[a] = (boundary - origin[a]) * inverse[a];
            t_delta[a] = self.size[a] * inverse[a].abs();
        }
        let mut t = t0;
        loop {
            let axis = if t_next[0] <= t_next[1] && t_next[0] <= t_next[2] {
                0
            } else if t_next[1] <= t_next[2] {
                1
            } else {
                2
            };
            let exit = t_next[axis].min(t1);
            let index = block[0] + self.dims[0] * (block[1] + self.dims[1] * block[2]);
            let here = class(index);
            if here != 0 {
                let (lo, hi) = (t - pad, exit + pad);
                match spans.last_mut() {
                    Some(last) if last.1 >= lo && last.2 == here => last.1 = hi,
                    Some(last) if last.1 >= lo => {
                        let meet = if last.2 < here {
                            last.1
                        } else {
                            last.1 = lo;
                            lo
                        };
                        spans.push((meet, hi, here));
                    }
                    _ => spans.push((lo, hi, here)),
                }
            }
            if exit >= t1 {
                return;
            }
            let next = block[axis] as isize + step[axis];
            if next < 0 || next >= self.dims[axis] as isize {
                // Rounding left the grid before t1: the rest lies in this edge block.
                if here != 0 {
                    spans.last_mut().expect("pushed above").1 = t1 + pad;
                }
                return;
            }
            block[axis] = next as usize;
            t = exit;
            t_next[axis] += t_delta[axis];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_blocks_share_their_boundary_vertices() {
        // 17 vertices along x: blocks [0, 8] and [8, 16]; the value at vertex 8 is in both.
        let grid = MacrocellGrid::over_grid([17, 2, 2], Vec3::ZERO, Vec3::ONE, |[i, _, _]| {
            if i == 8 { 5.0 } else { i as f32 / 100.0 }
        });
        assert_eq!(grid.dims, [2, 1, 1]);
        assert_eq!(grid.ranges()[0], (0.0, 5.0));
        assert_eq!(grid.ranges()[1], (0.09, 5.0));
    }

    #[test]
    fn the_dda_lists_occupied_blocks_in_ray_order() {
        // Four blocks along x, unit size; blocks 1 and 3 occupied.
        let grid = MacrocellGrid::over_grid([33, 2, 2], Vec3::ZERO, Vec3::splat(0.125), |_| 0.0);
        assert_eq!(grid.dims, [4, 1, 1]);
        let occupied = |index: usize| [0, 1, 0, 1][index];
        let mut spans = Vec::new();
        let origin = Vec3::new(-1.0, 0.05, 0.05);
        grid.classified_spans(occupied, origin, Vec3::X, (1.0, 5.0), &mut spans);
        let pad = 1e-3;
        let expected = [(2.0 - pad, 3.0 + pad), (4.0 - pad, 5.0 + pad)];
        assert_eq!(spans.len(), 2, "{spans:?}");
        for (got, want) in spans.iter().zip(expected) {
            assert!((got.0 - want.0).abs() < 1e-5 && (got.1 - want.1).abs() < 1e-5);
            assert_eq!(got.2, 1);
        }
        // Backwards along the same line.
        let origin = Vec3::new(5.0, 0.05, 0.05);
        grid.classified_spans(occupied, origin, Vec3::NEG_X, (1.0, 5.0), &mut spans);
        let expected = [(1.0 - pad, 2.0 + pad), (3.0 - pad, 4.0 + pad)];
        for (got, want) in spans.iter().zip(expected) {
            assert!((got.0 - want.0).abs() < 1e-5 && (got.1 - want.1).abs() < 1e-5);
        }
    }

    #[test]
    fn neighbouring_classes_meet_at_their_face_and_the_smaller_takes_the_margin() {
        let grid = MacrocellGrid::over_grid([33, 2, 2], Vec3::ZERO, Vec3::splat(0.125), |_| 0.0);
        let classes = |index: usize| [4, 1, 1, 4][index];
        let mut spans = Vec::new();
        let origin = Vec3::new(0.0, 0.05, 0.05);
        grid.classified_spans(classes, origin, Vec3::X, (0.0, 4.0), &mut spans);
        let pad = 1e-3;
        let expected = [
            (-pad, 1.0 - pad, 4),
            (1.0 - pad, 3.0 + pad, 1),
            (3.0 + pad, 4.0 + pad, 4),
        ];
        assert_eq!(spans.len(), 3, "{spans:?}");
        for (got, want) in spans.iter().zip(expected) {
            assert!((got.0 - want.0).abs() < 1e-5 && (got.1 - want.1).abs() < 1e-5);
            assert_eq!(got.2, want.2, "{spans:?}");
        }
    }
}
