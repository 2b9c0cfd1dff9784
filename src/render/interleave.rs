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
        match self.set {
            PixelSet::Rows(parity) => (s, 2 * t + parity),
            PixelSet::Columns(parity) => (2 * s + parity, t),
            PixelSet::Checkerboard(parity) => (2 * s + (t + parity) % 2, t),
            PixelSet::All | PixelSet::Anaglyph => (s, t),
        }
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
                    let tile = InterleavedTile {
                        set,
                        s0: 0,
                        t0: 0,
                        s1: lw,
                        t1: lh,
                        width,
                        height,
                    };
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
