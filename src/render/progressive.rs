//! Frame-time budgets (`ANARI_CAVETRACE_FRAME_BUDGET`): which pixels a budgeted render traces,
//! in which order, and how the pixels it did not trace are filled.
//!
//! Each eye's viewport is cut into 8×8 pixel blocks. The 64 positions of a block are traced
//! in the order of an 8×8 ordered-dither (Bayer) matrix — first one pixel per block, then the
//! one diagonally opposite, then the rest of a 4×4 lattice, and so on — so every prefix of the
//! order is spread evenly over the image. One position of every block of a viewport forms a
//! sub-image with a stride of 8 pixels, traced in tiles like a small frame: the *units* of
//! work. A budgeted render traces a prefix of the units (at least every block's first pixel,
//! so that every pixel has a traced neighbour) and the next render of an unchanged frame goes
//! on where the last one stopped. Both eyes of a stereo frame get the same positions, as the
//! pattern is laid relative to each eye's viewport and the eyes' units alternate.
//!
//! Untraced pixels copy every channel from the nearest pixel traced so far (never blended:
//! ids and depths stay values that exist in the scene).

use crate::camera::EyeViewport;

/// Side of the blocks whose pixel positions are traced one after another.
pub const BLOCK: u32 = 8;
/// Pixel positions in a block.
pub const POSITIONS: usize = (BLOCK * BLOCK) as usize;
/// Side, in sub-image pixels, of one unit's tile.
const UNIT_TILE: u32 = 32;

/// Value of the 8×8 Bayer matrix at (x, y): the rank of that block position.
const fn bayer_rank(x: u32, y: u32) -> u32 {
    // Interleave the bit-reversed bits of x XOR y and y (the recursive Bayer construction).
    let a = x ^ y;
    let mut rank = 0;
    let mut bit = 0;
    while bit < 3 {
        rank |= ((a >> bit) & 1) << (5 - 2 * bit);
        rank |= ((y >> bit) & 1) << (4 - 2 * bit);
        bit += 1;
    }
    rank
}

/// Block positions (dx, dy) in the order they are traced.
pub const ORDER: [(u32, u32); POSITIONS] = {
    let mut order = [(0, 0); POSITIONS];
    let mut y = 0;
    while y < BLOCK {
        let mut x = 0;
        while x < BLOCK {
            order[bayer_rank(x, y) as usize] = (x, y);
            x += 1;
        }
        y += 1;
    }
    order
};

/// The pixels `origin + stride·(s, t)` of a frame: a whole frame (stride 1) or one block
/// position of a viewport (stride [`BLOCK`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lattice {
    pub origin_x: u32,
    pub origin_y: u32,
    pub stride: u32,
}

impl Lattice {
    pub const WHOLE_FRAME: Lattice = Lattice {
        origin_x: 0,
        origin_y: 0,
        stride: 1,
    };

    #[inline]
    pub fn pixel(&self, s: u32, t: u32) -> (u32, u32) {
        (
            self.origin_x + self.stride * s,
            self.origin_y + self.stride * t,
        )
    }
}

/// A rectangle of a lattice's sub-image, `[s0, s1) × [t0, t1)`: one tile of work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Area {
    pub lattice: Lattice,
    pub s0: u32,
    pub t0: u32,
    pub s1: u32,
    pub t1: u32,
}

impl Area {
    pub fn pixel_count(&self) -> usize {
        ((self.s1 - self.s0) * (self.t1 - self.t0)) as usize
    }
}

/// Number of lattice points `start, start + BLOCK, …` below `end`.
fn lattice_count(start: u32, end: u32) -> u32 {
    if start >= end {
        0
    } else {
        (end - start).div_ceil(BLOCK)
    }
}

/// The units of a budgeted render of `viewports`, in tracing order, with the index of the
/// first unit of each block position (`first_unit[k]`, and the total at `POSITIONS`).
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub units: Vec<Area>,
    pub first_unit: [usize; POSITIONS + 1],
    pub viewports: Vec<EyeViewport>,
}

impl Plan {
    pub fn new(viewports: &[EyeViewport]) -> Plan {
        let viewports: Vec<EyeViewport> = viewports
            .iter()
            .copied()
            .filter(|v| v.width > 0 && v.height > 0)
            .collect();
        let mut units = Vec::new();
        let mut first_unit = [0; POSITIONS + 1];
        for (k, &(dx, dy)) in ORDER.iter().enumerate() {
            first_unit[k] = units.len();
            let lattices: Vec<(Lattice, u32, u32)> = viewports
                .iter()
                .map(|v| {
                    let lattice = Lattice {
                        origin_x: v.x + dx,
                        origin_y: v.y + dy,
                        stride: BLOCK,
                    };
                    let width = lattice_count(v.x + dx, v.x + v.width);
                    let height = lattice_count(v.y + dy, v.y + v.height);
                    (lattice, width, height)
                })
                .collect();
            let tiles_x: Vec<u32> = lattices
                .iter()
                .map(|(_, w, _)| w.div_ceil(UNIT_TILE))
                .collect();
            let tiles_y: Vec<u32> = lattices
                .iter()
                .map(|(_, _, h)| h.div_ceil(UNIT_TILE))
                .collect();
            // The eyes' tiles alternate, so a render that stops early has traced about as much
            // of each eye.
            let mut next = vec![0u32; viewports.len()];
            loop {
                let mut any = false;
                for (e, &(lattice, width, height)) in lattices.iter().enumerate() {
                    let count = tiles_x[e] * tiles_y[e];
                    if next[e] >= count {
                        continue;
                    }
                    any = true;
                    let (tx, ty) = (next[e] % tiles_x[e], next[e] / tiles_x[e]);
                    units.push(Area {
                        lattice,
                        s0: tx * UNIT_TILE,
                        t0: ty * UNIT_TILE,
                        s1: ((tx + 1) * UNIT_TILE).min(width),
                        t1: ((ty + 1) * UNIT_TILE).min(height),
                    });
                    next[e] += 1;
                }
                if !any {
                    break;
                }
            }
        }
        first_unit[POSITIONS] = units.len();
        Plan {
            units,
            first_unit,
            viewports,
        }
    }

    /// Units that must be traced before an image can be filled: every block's first pixel.
    pub fn mandatory_units(&self) -> usize {
        self.first_unit[1]
    }

    /// Pixels traced by the first `done` units.
    pub fn traced_pixels(&self, done: usize) -> usize {
        self.units[..done.min(self.units.len())]
            .iter()
            .map(Area::pixel_count)
            .sum()
    }

    /// For every untraced pixel after the first `done` units (at least
    /// [`Plan::mandatory_units`]), calls `copy(target, source)` with frame pixel indices:
    /// the nearest pixel of the same viewport whose block position was traced everywhere.
    pub fn fill(&self, width: u32, done: usize, mut copy: impl FnMut(usize, usize)) {
        // Block positions traced in every block.
        let complete = self.first_unit[1..]
            .iter()
            .take_while(|&&f| f <= done)
            .count();
        if complete == 0 || complete == POSITIONS {
            return;
        }
        let nearest = nearest_traced(complete);
        // Pixels of the block position the render stopped in the middle of.
        let mut partial = std::collections::HashSet::new();
        for unit in &self.units[self.first_unit[complete]..done] {
            for t in unit.t0..unit.t1 {
                for s in unit.s0..unit.s1 {
                    let (x, y) = unit.lattice.pixel(s, t);
                    partial.insert((y * width + x) as usize);
                }
            }
        }
        for v in &self.viewports {
            for y in v.y..v.y + v.height {
                for x in v.x..v.x + v.width {
                    let (dx, dy) = ((x - v.x) % BLOCK, (y - v.y) % BLOCK);
                    let rank = bayer_rank(dx, dy) as usize;
                    if rank < complete || partial.contains(&((y * width + x) as usize)) {
                        continue;
                    }
                    let (ox, oy) = nearest[(dy * BLOCK + dx) as usize];
                    let (sx, sy) = (x as i64 + ox as i64, y as i64 + oy as i64);
                    let inside = sx >= v.x as i64
                        && sy >= v.y as i64
                        && sx < (v.x + v.width) as i64
                        && sy < (v.y + v.height) as i64;
                    // The block's first pixel is always traced and always inside.
                    let (sx, sy) = if inside {
                        (sx as u32, sy as u32)
                    } else {
                        (x - dx, y - dy)
                    };
                    copy((y * width + x) as usize, (sy * width + sx) as usize);
                }
            }
        }
    }
}

/// For each block position (index dy·8 + dx), the offset to the nearest position among the
/// first `complete` of [`ORDER`] in this block or a neighbouring one (ties: the earlier
/// position, then the earlier block), so that copies are deterministic.
pub fn nearest_traced(complete: usize) -> [(i32, i32); POSITIONS] {
    let mut nearest = [(0, 0); POSITIONS];
    let block = BLOCK as i32;
    for dy in 0..block {
        for dx in 0..block {
            let mut best = (i32::MAX, (0, 0));
            for &(tx, ty) in &ORDER[..complete] {
                for by in [0, -1, 1] {
                    for bx in [0, -1, 1] {
                        let offset = (tx as i32 + bx * block - dx, ty as i32 + by * block - dy);
                        let distance = offset.0 * offset.0 + offset.1 * offset.1;
                        if distance < best.0 {
                            best = (distance, offset);
                        }
                    }
                }
            }
            nearest[(dy * block + dx) as usize] = best.1;
        }
    }
    nearest
}

/// Pixels per second a render can trace, measured on earlier budgeted renders of a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Throughput {
    /// Traced pixels per second of wall time (all threads), if measured.
    pub pixels_per_second: Option<f64>,
    /// Seconds the fill took last time.
    pub fill_seconds: f64,
}

impl Throughput {
    /// Blends in a new measurement (the newest counts most: head motion changes the view).
    pub fn record(&mut self, pixels: usize, seconds: f64) {
        if pixels < 1024 || seconds <= 0.0 {
            return;
        }
        let rate = pixels as f64 / seconds;
        self.pixels_per_second = Some(match self.pixels_per_second {
            Some(old) => 0.5 * old + 0.5 * rate,
            None => rate,
        });
    }

    /// Pixels to trace within `budget` seconds. Before any measurement the guess is from the
    /// scene's size: a primary ray through a BVH of n primitives costs about
    /// (60 + 8·log2 n) ns per thread with the fast renderer, three times that with the default
    /// renderer (shading, shadows), on the development machine.
    pub fn pixels_for(&self, budget: f64, primitives: usize, fast: bool, threads: usize) -> f64 {
        let rate = self.pixels_per_second.unwrap_or_else(|| {
            let per_ray = (60.0 + 8.0 * ((primitives + 1) as f64).log2()) * 1e-9;
            let per_ray = if fast { per_ray } else { 3.0 * per_ray };
            threads.max(1) as f64 / per_ray
        });
        // Keep a margin for the frame's set-up, the fill and timing noise.
        (rate * (0.8 * budget - self.fill_seconds)).max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Eye, StereoMode};

    #[test]
    fn bayer_order_visits_every_position_once_and_spreads_each_prefix() {
        let mut seen = [false; POSITIONS];
        for &(x, y) in &ORDER {
            assert!(!seen[(y * BLOCK + x) as usize]);
            seen[(y * BLOCK + x) as usize] = true;
        }
        assert_eq!(ORDER[0], (0, 0));
        assert_eq!(ORDER[1], (4, 4));
        // The first 4 positions form a 4×4 lattice, the first 16 a 2×2 one.
        let mut first4: Vec<_> = ORDER[..4].to_vec();
        first4.sort();
        assert_eq!(first4, vec![(0, 0), (0, 4), (4, 0), (4, 4)]);
        assert!(ORDER[..16].iter().all(|&(x, y)| x % 2 == 0 && y % 2 == 0));
    }

    #[test]
    fn units_cover_every_pixel_of_every_viewport_exactly_once() {
        for (width, height, mode) in [
            (37, 21, StereoMode::None),
            (100, 40, StereoMode::SideBySide),
            (64, 31, StereoMode::TopBottom),
        ] {
            let plan = Plan::new(&mode.viewports(width, height));
            let mut count = vec![0u32; (width * height) as usize];
            for unit in &plan.units {
                for t in unit.t0..unit.t1 {
                    for s in unit.s0..unit.s1 {
                        let (x, y) = unit.lattice.pixel(s, t);
                        assert!(x < width && y < height, "{unit:?}");
                        count[(y * width + x) as usize] += 1;
                    }
                }
            }
            assert!(count.iter().all(|&c| c == 1), "{width}×{height} {mode:?}");
            assert_eq!(
                plan.traced_pixels(plan.units.len()),
                (width * height) as usize
            );
        }
    }

    #[test]
    fn fill_copies_only_from_traced_pixels_of_the_same_eye_for_every_prefix() {
        let viewports = StereoMode::SideBySide.viewports(90, 70);
        let plan = Plan::new(&viewports);
        assert_eq!(plan.units.len(), 128);
        for done in [
            plan.mandatory_units(),
            plan.mandatory_units() + 1,
            40,
            77,
            127,
        ] {
            let mut traced = vec![false; 90 * 70];
            for unit in &plan.units[..done] {
                for t in unit.t0..unit.t1 {
                    for s in unit.s0..unit.s1 {
                        let (x, y) = unit.lattice.pixel(s, t);
                        traced[(y * 90 + x) as usize] = true;
                    }
                }
            }
            let mut filled = vec![false; 90 * 70];
            plan.fill(90, done, |target, source| {
                assert!(traced[source], "source {source} untraced (done {done})");
                assert!(!traced[target]);
                // Same eye: side by side halves are 45 pixels wide.
                assert_eq!(target % 90 < 45, source % 90 < 45);
                filled[target] = true;
            });
            for k in 0..90 * 70 {
                assert!(traced[k] ^ filled[k], "pixel {k}, done {done}");
            }
        }
    }

    #[test]
    fn each_eye_gets_the_same_pixel_positions() {
        let plan = Plan::new(&StereoMode::SideBySide.viewports(64, 16));
        let eyes: Vec<Eye> = plan.viewports.iter().map(|v| v.eye).collect();
        assert_eq!(eyes, vec![Eye::Left, Eye::Right]);
        // Units alternate between the eyes, at the same place relative to each viewport.
        for pair in plan.units.chunks(2) {
            let [left, right] = pair else { panic!() };
            assert_eq!(right.lattice.origin_x - left.lattice.origin_x, 32);
            assert_eq!(right.lattice.origin_y, left.lattice.origin_y);
            assert_eq!(
                (left.s0, left.t0, left.s1, left.t1),
                (right.s0, right.t0, right.s1, right.t1)
            );
        }
    }

    #[test]
    fn nearest_traced_points_at_traced_positions() {
        for complete in 1..POSITIONS {
            let nearest = nearest_traced(complete);
            for dy in 0..BLOCK as i32 {
                for dx in 0..BLOCK as i32 {
                    let (ox, oy) = nearest[(dy * 8 + dx) as usize];
                    let (tx, ty) = (
                        (dx + ox).rem_euclid(8) as u32,
                        (dy + oy).rem_euclid(8) as u32,
                    );
                    assert!(ORDER[..complete].contains(&(tx, ty)));
                    assert!(ox.abs() <= 8 && oy.abs() <= 8);
                }
            }
        }
        // With one position per block, every pixel copies the nearest block corner.
        let nearest = nearest_traced(1);
        assert_eq!(nearest[(3 * 8 + 3) as usize], (-3, -3));
        assert_eq!(nearest[(3 * 8 + 5) as usize], (3, -3));
        assert_eq!(nearest[(7 * 8 + 7) as usize], (1, 1));
    }
}
