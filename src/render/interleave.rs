//! Tiles of one eye of an interleaved stereo frame: the eye's pixels (every other row, column
//! or checkerboard square) as a dense lattice, so that a packet holds rays of one eye only,
//! side by side as in a mono frame.

use crate::camera::PixelSet;
use crate::render::progressive::{Area, BlockPixels, Lattice, PointRow, TileMap};

/// A rectangle `[s0, s1) × [t0, t1)` of the lattice of one eye's pixels of a `width`×`height`
/// frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InterleavedTile {
    pub set: PixelSet,
    pub s0: u32,
    pub t0: u32,
    pub s1: u32,
    pub t1: u32,
    pub width: u32,
    pub height: u32,
    /// `set`'s lattice point → pixel, without a branch per pixel.
    steps: PixelSteps,
}

/// Lattice point (s, t) of a pixel set is pixel
/// (`across`·s + `shift`·((t + `parity`) mod 2) + `x0`, `up`·t + `y0`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PixelSteps {
    across: u32,
    shift: u32,
    parity: u32,
    x0: u32,
    up: u32,
    y0: u32,
}

impl PixelSteps {
    fn of(set: PixelSet) -> PixelSteps {
        let steps = |across, shift, parity, x0, up, y0| PixelSteps {
            across,
            shift,
            parity,
            x0,
            up,
            y0,
        };
        match set {
            PixelSet::Rows(parity) => steps(1, 0, 0, 0, 2, parity),
            PixelSet::Columns(parity) => steps(2, 0, 0, parity, 1, 0),
            PixelSet::Checkerboard(parity) => steps(2, 1, parity, 0, 1, 0),
            PixelSet::All | PixelSet::Anaglyph => steps(1, 0, 0, 0, 1, 0),
        }
    }
}

impl InterleavedTile {
    /// The tile `[s0, s1) × [t0, t1)` of `set`'s lattice in a frame of `size` (width, height).
    pub fn new(
        set: PixelSet,
        (s0, t0): (u32, u32),
        (s1, t1): (u32, u32),
        size: (u32, u32),
    ) -> Self {
        InterleavedTile {
            set,
            s0,
            t0,
            s1,
            t1,
            width: size.0,
            height: size.1,
            steps: PixelSteps::of(set),
        }
    }
}

/// Size of the lattice of `set`'s pixels in a `width`×`height` frame (points outside the frame
/// are skipped).
pub fn lattice_size(set: PixelSet, width: u32, height: u32) -> (u32, u32) {
    match set {
        PixelSet::Rows(_) => (width, height.div_ceil(2)),
        PixelSet::Columns(_) | PixelSet::Checkerboard(_) => (width.div_ceil(2), height),
        PixelSet::All | PixelSet::Anaglyph => (width, height),
    }
}

impl TileMap for InterleavedTile {
    fn area(&self) -> Area {
        Area {
            lattice: Lattice::WHOLE_FRAME,
            s0: self.s0,
            t0: self.t0,
            s1: self.s1,
            t1: self.t1,
            skips_coarser: false,
        }
    }

    #[inline]
    fn pixel(&self, s: u32, t: u32) -> (u32, u32) {
        let PixelSteps {
            across,
            shift,
            parity,
            x0,
            up,
            y0,
        } = self.steps;
        (across * s + shift * ((t + parity) % 2) + x0, up * t + y0)
    }

    #[inline]
    fn skips(&self, s: u32, t: u32) -> bool {
        let (x, y) = self.pixel(s, t);
        x >= self.width || y >= self.height
    }

    fn stride(&self) -> u32 {
        1
    }

    fn rectangle_origin(&self) -> Option<(u32, u32)> {
        None
    }

    fn pixels(&self) -> PixelSet {
        self.set
    }

    /// A row of a lattice whose points step one pixel across (an eye's rows of a
    /// rowInterleaved frame) is a run of one frame row, cut at the frame's right edge; a row
    /// past the top is skipped.
    #[inline]
    fn point_row(&self, t: u32) -> Option<PointRow> {
        if self.steps.across != 1 {
            return None;
        }
        let (x, y) = self.pixel(self.s0, t);
        let count = match y < self.height && x < self.width {
            true => (self.s1 - self.s0).min(self.width - x),
            false => 0,
        };
        Some(PointRow { x, y, count })
    }

    /// A point's column is `across`·s plus a shift by its t's parity, its row `up`·t: both
    /// grow with s and t, so the block's last column and row tell whether it leaves the frame.
    #[inline]
    fn block_pixels<const N: usize>(&self, s: u32, t: u32) -> Option<BlockPixels<N>> {
        let columns = [t, t + 1].map(|t| std::array::from_fn(|i| self.pixel(s + i as u32, t).0));
        let rows = std::array::from_fn(|j| self.pixel(s, t + j as u32).1);
        let last_column = columns[0][N - 1].max(columns[1][N - 1]);
        (last_column < self.width && rows[N - 1] < self.height)
            .then_some(BlockPixels { columns, rows })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_eyes_lattice_covers_exactly_its_pixels_once() {
        for (width, height) in [(8, 8), (7, 5), (1, 1), (33, 2)] {
            for set_of in [PixelSet::Rows, PixelSet::Columns, PixelSet::Checkerboard] {
                let mut seen = vec![0u32; (width * height) as usize];
                for parity in 0..2 {
                    let set = set_of(parity);
                    let (lw, lh) = lattice_size(set, width, height);
                    let tile = InterleavedTile::new(set, (0, 0), (lw, lh), (width, height));
                    for t in 0..lh {
                        for s in 0..lw {
                            if tile.skips(s, t) {
                                continue;
                            }
                            let (x, y) = tile.pixel(s, t);
                            assert!(set.holds(x, y), "{set:?} ({s}, {t}) -> ({x}, {y})");
                            seen[(y * width + x) as usize] += 1;
                        }
                    }
                }
                assert!(
                    seen.iter().all(|n| *n == 1),
                    "{width}x{height} {set_of:?}: {seen:?}"
                );
            }
        }
    }

    #[test]
    fn block_pixels_are_each_points_pixel_and_none_where_a_point_is_skipped() {
        let (width, height) = (21, 19);
        for set_of in [PixelSet::Rows, PixelSet::Columns, PixelSet::Checkerboard] {
            for parity in 0..2 {
                let set = set_of(parity);
                let (lw, lh) = lattice_size(set, width, height);
                let tile = InterleavedTile::new(set, (0, 0), (lw, lh), (width, height));
                let (mut whole, mut partial) = (0, 0);
                for t in 0..lh {
                    for s in 0..lw {
                        let points = (0..4).flat_map(|j| (0..4).map(move |i| (s + i, t + j)));
                        let skipped = points.clone().any(|(s, t)| tile.skips(s, t));
                        let Some(block) = tile.block_pixels::<4>(s, t) else {
                            assert!(skipped, "{set:?} ({s}, {t}): no block, no point skipped");
                            partial += 1;
                            continue;
                        };
                        assert!(!skipped, "{set:?} ({s}, {t}): a block over a skipped point");
                        whole += 1;
                        for (ps, pt) in points {
                            let (i, j) = ((ps - s) as usize, (pt - t) as usize);
                            let pixel = (block.columns[j % 2][i], block.rows[j]);
                            assert_eq!(pixel, tile.pixel(ps, pt), "{set:?} ({ps}, {pt})");
                        }
                    }
                }
                assert!(
                    whole > 0 && partial > 0,
                    "{set:?}: {whole} whole, {partial}"
                );
            }
        }
    }
}
