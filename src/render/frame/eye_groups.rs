//! A light-field tile's subpixel rays traced eight at a time, grouped by eye.
//!
//! A light-field display's neighbouring subpixels look from eyes centimetres apart, so eight
//! rays in pixel order part within a few levels of the BVH and cost what they cost one by one.
//! Rays of one eye (snapped views) or of neighbouring eyes (continuous views) stay together
//! much longer: the tile's blocks of subpixel rays are made first ([`EyeGroups::commit`]), sorted
//! by eye, traced eight at a time through [`SceneBvh::intersect8`] (each hit the record
//! `intersect_into` gives) and handed back block by block for shading ([`EyeGroups::replay`]),
//! in the order they were made.
//!
//! The eyes of a light-field display lie on one line (the viewing line), so sorting by the
//! origin's coordinate on the axis along which the tile's origins spread most sorts them along
//! it; a counting sort into [`BUCKETS`] buckets keeps that linear in the rays. Ties keep the
//! order the rays were made in (pass, block, lane): rays of one eye close on the screen stay
//! neighbours.

use glam::Vec3;

use crate::accel::{Ray, SceneBvh, SceneHit};
use crate::camera::{BLOCK_RAYS, BlockRays};

use super::tile::traced_lane;

/// Buckets of the sort by eye (a bucket is a `u8`): finer than the 45 to 100 views of a
/// display, so that snapped views fall into buckets of their own.
const BUCKETS: usize = 256;

/// Rays traced together.
const EIGHT: usize = 8;

/// A tile's blocks of subpixel rays (each a pass's 8×8 pixels for one sample), their hits and
/// where each made block is in the store.
#[derive(Default)]
pub(super) struct EyeGroups {
    /// The blocks made together ([`BlockRays`]), in the order they were made: the first
    /// `stored`; the others are kept from earlier tiles to be written over.
    blocks: Vec<BlockRays>,
    stored: usize,
    /// Per block of the tile: its index in `blocks`, or `None` for a block the frame traces and
    /// shades as before (not made together).
    entries: Vec<Option<u32>>,
    /// `BLOCK_RAYS` per stored block: the rays to trace, one after another.
    rays: Vec<Ray>,
    /// Per ray: its bucket of the sort by eye.
    buckets: Vec<u8>,
    /// Ray indices (block × `BLOCK_RAYS` + lane) sorted by eye.
    order: Vec<u32>,
    /// `BLOCK_RAYS` per stored block: each ray's closest hit.
    hits: Vec<Option<SceneHit>>,
    /// The next entry [`EyeGroups::replay`] hands back.
    cursor: usize,
}

impl EyeGroups {
    /// Forgets the previous tile's blocks.
    pub(super) fn clear(&mut self) {
        self.stored = 0;
        self.entries.clear();
        self.rays.clear();
        self.cursor = 0;
    }

    /// Where the tile's next block is made (kept by [`EyeGroups::commit`]`(true)`).
    pub(super) fn next_block(&mut self) -> &mut BlockRays {
        if self.blocks.len() == self.stored {
            self.blocks.push(BlockRays::default());
        }
        &mut self.blocks[self.stored]
    }

    /// Ends the tile's next block: its rays were made together in [`EyeGroups::next_block`]
    /// (`made`: stored to be traced), or not (it will be made and traced when shaded).
    pub(super) fn commit(&mut self, made: bool) {
        if !made {
            self.entries.push(None);
            return;
        }
        let block = &self.blocks[self.stored];
        self.rays
            .extend((0..BLOCK_RAYS).map(|lane| traced_lane(block, lane)));
        self.entries.push(Some(self.stored as u32));
        self.stored += 1;
    }

    /// Traces the stored blocks' rays grouped by eye, eight at a time.
    pub(super) fn trace(&mut self, bvh: &SceneBvh) {
        self.hits.clear();
        self.hits.resize(self.rays.len(), None);
        self.sort_by_eye();
        let rays = &self.rays;
        let mut eights = self.order.chunks_exact(EIGHT);
        let mut found = [None; EIGHT];
        for eight in &mut eights {
            let eight: &[u32; EIGHT] = eight.try_into().expect("chunks of eight");
            bvh.intersect8(&eight.map(|index| rays[index as usize]), &mut found);
            for (&index, hit) in eight.iter().zip(&found) {
                self.hits[index as usize] = *hit;
            }
        }
        for &index in eights.remainder() {
            let index = index as usize;
            bvh.intersect_into(&rays[index], &mut self.hits[index]);
        }
    }

    /// `order`: every stored ray, sorted by its origin's coordinate on the axis along which the
    /// origins spread most (a counting sort into [`BUCKETS`] buckets, stable).
    fn sort_by_eye(&mut self) {
        let (mut low, mut high) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for ray in &self.rays {
            low = low.min(ray.origin);
            high = high.max(ray.origin);
        }
        let spread = high - low;
        let axis = spread.max_position();
        let scale = if spread[axis] > 0.0 {
            (BUCKETS as f32 - 1.0) / spread[axis]
        } else {
            0.0
        };
        let mut counts = [0u32; BUCKETS];
        self.buckets.clear();
        self.buckets.extend(self.rays.iter().map(|ray| {
            // A NaN goes to bucket 0 (`as` saturates).
            let bucket = ((ray.origin[axis] - low[axis]) * scale) as u8;
            counts[usize::from(bucket)] += 1;
            bucket
        }));
        let mut start = 0;
        for count in &mut counts {
            let next = start + *count;
            *count = start;
            start = next;
        }
        self.order.clear();
        self.order.resize(self.rays.len(), 0);
        for (index, &bucket) in self.buckets.iter().enumerate() {
            let slot = &mut counts[usize::from(bucket)];
            self.order[*slot as usize] = index as u32;
            *slot += 1;
        }
    }

    /// The tile's next block: its index among the stored ones if its rays were made together
    /// (see [`EyeGroups::stored`]), else `None` (the caller makes and traces it).
    pub(super) fn replay(&mut self) -> Option<usize> {
        let entry = self.entries.get(self.cursor).copied().flatten();
        self.cursor += 1;
        entry.map(|index| index as usize)
    }

    /// Stored block `index`'s rays and their hits.
    pub(super) fn stored(&self, index: usize) -> (&BlockRays, &[Option<SceneHit>; BLOCK_RAYS]) {
        let hits = &self.hits[index * BLOCK_RAYS..(index + 1) * BLOCK_RAYS];
        (
            &self.blocks[index],
            hits.try_into().expect("a block's hits"),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_are_sorted_by_eye_stably() {
        // Three blocks whose lanes look from five eyes on a slanted line, interleaved as a
        // panel's subpixels are; one block is not made together.
        let eye = |lane: usize, block: usize| (lane * 7 + block * 3) % 5;
        let mut groups = EyeGroups::default();
        groups.clear();
        for block in 0..4 {
            let made = block != 2;
            let target = groups.next_block();
            for lane in 0..BLOCK_RAYS {
                let e = eye(lane, block) as f32;
                target.origin[0][lane] = 0.03 * e - 0.06;
                target.origin[1][lane] = 1.5 - 0.01 * e;
                target.origin[2][lane] = 1.0;
                target.direction[2][lane] = -1.0;
            }
            groups.commit(made);
        }
        groups.sort_by_eye();
        let stored_blocks = [0, 1, 3];
        let eye_of = |index: u32| {
            let index = index as usize;
            eye(index % BLOCK_RAYS, stored_blocks[index / BLOCK_RAYS])
        };
        let mut seen = groups.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..3 * BLOCK_RAYS as u32).collect::<Vec<_>>());
        for pair in groups.order.windows(2) {
            let (a, b) = (eye_of(pair[0]), eye_of(pair[1]));
            assert!(
                a < b || (a == b && pair[0] < pair[1]),
                "{pair:?}: eyes {a}, {b}"
            );
        }
        assert_eq!(groups.replay(), Some(0), "the first block comes back first");
        assert_eq!(groups.replay(), Some(1));
        assert_eq!(groups.replay(), None, "the block not made together");
        assert_eq!(groups.replay(), Some(2));
    }
}
