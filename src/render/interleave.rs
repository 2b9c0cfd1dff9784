//! Tiles of one eye of an interleaved stereo frame: the eye's pixels (every other row, column
//! or checkerboard square) as a dense lattice, so that a packet holds rays of one eye only,
//! side by side as in a mono frame.

use crate::camera::PixelSet;
use crate::render::progressive::{Area, Lattice, TileMap};

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
}
