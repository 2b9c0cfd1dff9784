//! A binned surface-area-heuristic (SAH) builder of the binary BVH for whole leaves
//! (`LeafSizing::Whole`: triangles and quads).
//!
//! Top-down: each range of primitives is split where the surface area heuristic is least,
//! found by binning the doubled centroids (box minimum plus maximum) into bins along each of
//! the three axes (32 bins for 128 primitives and more, 16 from 24, else 4). A leaf holds at
//! most [`MAX_PRIMS_PER_LEAF`] primitives and is tested as one group whatever its count, so a
//! side of a split costs its half area times the groups of four it needs (as Embree sizes its
//! leaves by its block size): splits fill leaves toward four.
//!
//! The caller's boxes are partitioned in place beside the primitive indices; the ranges below
//! [`SEQUENTIAL_BELOW`] primitives are built by one task each into a node list of their own,
//! the ranges above by `rayon::join` (binning the largest in parallel chunks), and [`place`]
//! stitches the lists into obvhs' layout (children of a node side by side).

use glam::{Vec3A, Vec4};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use rayon::iter::{IntoParallelIterator, ParallelIterator};
use rayon::slice::ParallelSlice;

use crate::accel::wide_bvh::MAX_PRIMS_PER_LEAF;

/// Ranges of fewer primitives are built by one task, into a node list of their own.
const SEQUENTIAL_BELOW: usize = 1 << 12;
/// Ranges of at least this many primitives are binned in parallel chunks.
const PARALLEL_BINNING_FROM: usize = 1 << 17;
/// The chunk size of parallel binning and of the set-up passes.
const CHUNK: usize = 1 << 14;

/// A range's primitive bounds and the bounds of its doubled centroids.
#[derive(Clone, Copy)]
struct Range {
    bounds: Aabb,
    centroids: Aabb,
}

impl Range {
    fn empty() -> Range {
        Range {
            bounds: Aabb::empty(),
            centroids: Aabb::empty(),
        }
    }

    fn add(&mut self, aabb: &Aabb) {
        let centroid = aabb.min + aabb.max;
        self.bounds.min = self.bounds.min.min(aabb.min);
        self.bounds.max = self.bounds.max.max(aabb.max);
        self.centroids.min = self.centroids.min.min(centroid);
        self.centroids.max = self.centroids.max.max(centroid);
    }

    fn union(self, other: Range) -> Range {
        Range {
            bounds: self.bounds.union(&other.bounds),
            centroids: self.centroids.union(&other.centroids),
        }
    }

    fn of(boxes: &[Aabb]) -> Range {
        let mut range = Range::empty();
        boxes.iter().for_each(|aabb| range.add(aabb));
        range
    }
}

/// Surface-area cost of a side holding `count` primitives: its leaves are tested in groups of
/// [`MAX_PRIMS_PER_LEAF`], each group costing the same whatever its count.
fn side_cost(half_area: f32, count: u32) -> f32 {
    half_area * count.div_ceil(MAX_PRIMS_PER_LEAF) as f32
}

/// Added to a value in `[0, 2^22)`, rounds it to an integer in the low mantissa bits.
const ROUNDING: f32 = 8_388_608.0;

/// Maps doubled centroids to `B` bins per axis over a range's centroid bounds.
#[derive(Clone, Copy)]
struct Binning<const B: usize> {
    origin: Vec3A,
    scale: Vec3A,
}

impl<const B: usize> Binning<B> {
    fn new(centroids: &Aabb) -> Self {
        let extent = centroids.max - centroids.min;
        // Slightly under `B` so that the largest centroid lands in the last bin.
        let scale = Vec3A::select(
            extent.cmpgt(Vec3A::ZERO),
            Vec3A::splat(B as f32 * 0.99999) / extent,
            Vec3A::ZERO,
        );
        Binning {
            origin: centroids.min,
            scale,
        }
    }

    /// The bins of `aabb` along each axis. Rounding `position - 0.5` to the nearest integer
    /// by adding 2^23 (where the float spacing is 1) and reading the low bits is cheaper than
    /// three saturating conversions; the clamp keeps NaN and out-of-range positions in the
    /// end bins.
    fn bins(&self, aabb: &Aabb) -> [usize; 3] {
        let position = (aabb.min + aabb.max - self.origin) * self.scale - Vec3A::splat(0.5);
        let clamped = position.max(Vec3A::ZERO).min(Vec3A::splat(B as f32 - 1.0));
        let rounded = clamped + Vec3A::splat(ROUNDING);
        // `B` is a power of two: the mask keeps the index in range for the compiler too.
        rounded
            .to_array()
            .map(|value| value.to_bits() as usize & (B - 1))
    }

    /// The bin along `axis` of a doubled centroid whose coordinate there is `doubled`:
    /// [`Binning::bins`]' operations on one lane, so the same bin.
    fn bin(&self, doubled: f32, axis: usize) -> usize {
        let position = (doubled - self.origin[axis]) * self.scale[axis] - 0.5;
        let clamped = position.max(0.0).min(B as f32 - 1.0);
        (clamped + ROUNDING).to_bits() as usize & (B - 1)
    }

    /// The greatest doubled-centroid coordinate along `axis` whose bin is below `position`
    /// (at least 1): every step of [`Binning::bin`] is monotonic, so a primitive's bin is
    /// below `position` exactly when its coordinate is at most this. Found by galloping and
    /// halving over the ordered floats from the exact bin boundary's estimate.
    fn threshold(&self, axis: usize, position: usize) -> f32 {
        // Floats (infinities included) as integers in the same order, and back.
        let key = |value: f32| {
            let bits = value.to_bits() as i32;
            if bits < 0 { bits ^ i32::MAX } else { bits }
        };
        let value = |key: i32| f32::from_bits((if key < 0 { key ^ i32::MAX } else { key }) as u32);
        let below = |key: i32| self.bin(value(key), axis) < position;
        let (lowest, highest) = (key(f32::NEG_INFINITY), key(f32::INFINITY));
        let estimate = self.origin[axis] + position as f32 / self.scale[axis];
        let estimate = if estimate.is_nan() { 0 } else { key(estimate) };
        // Gallop to a bracket: `below(low)` holds and `below(high)` does not (or high is past
        // the end).
        let (mut low, mut high);
        if below(estimate) {
            low = estimate;
            let mut step = 1i64;
            loop {
                let next = (i64::from(low) + step).min(i64::from(highest) + 1);
                if next > i64::from(highest) || !below(next as i32) {
                    high = next;
                    break;
                }
                low = next as i32;
                step *= 2;
            }
        } else {
            high = i64::from(estimate);
            let mut step = 1i64;
            loop {
                let next = (high - step).max(i64::from(lowest));
                if below(next as i32) {
                    low = next as i32;
                    break;
                }
                high = next;
                step *= 2;
            }
        }
        while i64::from(low) + 1 < high {
            let middle = ((i64::from(low) + high) / 2) as i32;
            if below(middle) {
                low = middle;
            } else {
                high = i64::from(middle);
            }
        }
        value(low)
    }
}

/// Per axis and bin: the union of the primitive boxes and their count.
struct Bins<const B: usize> {
    /// The boxes' minimum, and in `w` their count: one load and store per bin update
    /// instead of two. The count is a float, exact below 2^24 primitives per range (above,
    /// rounding may perturb the cost a little; a non-empty side never counts zero).
    lower: [[Vec4; B]; 3],
    upper: [[Vec3A; B]; 3],
}

/// Added to a bin's `lower` after the minimum: `-0.0` leaves every coordinate as it is,
/// `w` counts one more primitive.
const ONE_MORE: Vec4 = Vec4::new(-0.0, -0.0, -0.0, 1.0);

/// Where a range is split: primitives whose bin along `axis` is below `position` go left.
#[derive(Clone, Copy)]
struct Split {
    axis: usize,
    position: usize,
    /// The bounds of the primitive boxes going left and right.
    bounds: [Aabb; 2],
}

impl<const B: usize> Bins<B> {
    fn empty() -> Self {
        Bins {
            lower: [[Vec3A::splat(f32::MAX).extend(0.0); B]; 3],
            upper: [[Vec3A::splat(f32::MIN); B]; 3],
        }
    }

    fn add(&mut self, binning: &Binning<B>, boxes: &[Aabb]) {
        for aabb in boxes {
            let bins = binning.bins(aabb);
            // `w` infinite: the minimum keeps the count.
            let low = aabb.min.extend(f32::INFINITY);
            for (axis, &bin) in bins.iter().enumerate() {
                self.lower[axis][bin] = self.lower[axis][bin].min(low) + ONE_MORE;
                self.upper[axis][bin] = self.upper[axis][bin].max(aabb.max);
            }
        }
    }

    fn merge(mut self, other: Self) -> Self {
        for axis in 0..3 {
            for bin in 0..B {
                let (mine, theirs) = (self.lower[axis][bin], other.lower[axis][bin]);
                self.lower[axis][bin] =
                    Vec3A::from_vec4(mine.min(theirs)).extend(mine.w + theirs.w);
                self.upper[axis][bin] = self.upper[axis][bin].max(other.upper[axis][bin]);
            }
        }
        self
    }

    /// The least-cost split between bins with primitives on both sides, if any.
    fn best_split(&self) -> Option<Split> {
        let half_area = |lower: Vec3A, upper: Vec3A| {
            let d = upper - lower;
            (d.x + d.y) * d.z + d.x * d.y
        };
        let mut best: Option<(f32, usize, usize)> = None;
        for axis in 0..3 {
            let lower: [Vec3A; B] =
                std::array::from_fn(|bin| Vec3A::from_vec4(self.lower[axis][bin]));
            let counts: [u32; B] = std::array::from_fn(|bin| self.lower[axis][bin].w as u32);
            let upper = &self.upper[axis];
            // right_costs[i], right_counts[i]: bins i.. together.
            let mut right_costs = [0.0f32; B];
            let mut right_counts = [0u32; B];
            let (mut right_lower, mut right_upper, mut right_count) =
                (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN), 0);
            for bin in (1..B).rev() {
                right_lower = right_lower.min(lower[bin]);
                right_upper = right_upper.max(upper[bin]);
                right_count += counts[bin];
                right_costs[bin] = side_cost(half_area(right_lower, right_upper), right_count);
                right_counts[bin] = right_count;
            }
            let (mut left_lower, mut left_upper, mut left_count) =
                (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN), 0);
            for position in 1..B {
                left_lower = left_lower.min(lower[position - 1]);
                left_upper = left_upper.max(upper[position - 1]);
                left_count += counts[position - 1];
                if left_count == 0 || right_counts[position] == 0 {
                    continue;
                }
                let cost = side_cost(half_area(left_lower, left_upper), left_count)
                    + right_costs[position];
                if best.is_none_or(|(least, _, _)| cost < least) {
                    best = Some((cost, axis, position));
                }
            }
        }
        let (_, axis, position) = best?;
        let mut bounds = [Aabb::empty(); 2];
        for bin in 0..B {
            let side = &mut bounds[usize::from(bin >= position)];
            side.min = side.min.min(Vec3A::from_vec4(self.lower[axis][bin]));
            side.max = side.max.max(self.upper[axis][bin]);
        }
        Some(Split {
            axis,
            position,
            bounds,
        })
    }
}

/// Bins `boxes` (in parallel chunks when there are many) and returns the best split.
fn find_split<const B: usize>(boxes: &[Aabb], range: &Range) -> Option<(Binning<B>, Split)> {
    let binning = Binning::<B>::new(&range.centroids);
    let bins = if boxes.len() >= PARALLEL_BINNING_FROM {
        boxes
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut bins = Bins::<B>::empty();
                bins.add(&binning, chunk);
                bins
            })
            .reduce(Bins::empty, Bins::merge)
    } else {
        let mut bins = Bins::<B>::empty();
        bins.add(&binning, boxes);
        bins
    };
    bins.best_split().map(|split| (binning, split))
}

/// Moves the primitives for which `goes_left` holds to the front (indices alongside) and
/// returns their count and the bounds of the doubled centroids on both sides.
fn partition(
    boxes: &mut [Aabb],
    indices: &mut [u32],
    goes_left: impl Fn(&Aabb) -> bool,
) -> (usize, [Aabb; 2]) {
    let (mut left, mut right) = (Aabb::empty(), Aabb::empty());
    let add = |centroids: &mut Aabb, aabb: &Aabb| {
        let centroid = aabb.min + aabb.max;
        centroids.min = centroids.min.min(centroid);
        centroids.max = centroids.max.max(centroid);
    };
    let (mut begin, mut end) = (0, boxes.len());
    loop {
        while begin < end && goes_left(&boxes[begin]) {
            add(&mut left, &boxes[begin]);
            begin += 1;
        }
        while begin < end && !goes_left(&boxes[end - 1]) {
            add(&mut right, &boxes[end - 1]);
            end -= 1;
        }
        if begin == end {
            return (begin, [left, right]);
        }
        // boxes[begin] goes right, boxes[end - 1] left.
        add(&mut right, &boxes[begin]);
        add(&mut left, &boxes[end - 1]);
        boxes.swap(begin, end - 1);
        indices.swap(begin, end - 1);
        begin += 1;
        end -= 1;
    }
}

/// Below this depth ranges are split in the middle: the binned SAH may peel a few primitives
/// off a range level after level (centroids spread over many scales), and the recursion must
/// stay shallow.
const MAX_SAH_DEPTH: u32 = 64;

/// Splits a range of more than one primitive in two (both sides non-empty): at the binned
/// SAH's best split, else (all centroids in one bin, or at depth [`MAX_SAH_DEPTH`]) near the
/// middle.
fn split(
    boxes: &mut [Aabb],
    indices: &mut [u32],
    range: &Range,
    depth: u32,
) -> (usize, Range, Range) {
    fn binned<const B: usize>(
        boxes: &mut [Aabb],
        indices: &mut [u32],
        range: &Range,
    ) -> Option<(usize, Range, Range)> {
        let (binning, split) = find_split::<B>(boxes, range)?;
        let threshold = binning.threshold(split.axis, split.position);
        let (middle, centroids) = match split.axis {
            0 => partition(boxes, indices, |aabb| aabb.min.x + aabb.max.x <= threshold),
            1 => partition(boxes, indices, |aabb| aabb.min.y + aabb.max.y <= threshold),
            _ => partition(boxes, indices, |aabb| aabb.min.z + aabb.max.z <= threshold),
        };
        debug_assert!(boxes.iter().enumerate().all(|(at, aabb)| {
            let doubled = aabb.min[split.axis] + aabb.max[split.axis];
            (binning.bin(doubled, split.axis) < split.position) == (at < middle)
        }));
        let side = |side: usize| Range {
            bounds: split.bounds[side],
            centroids: centroids[side],
        };
        Some((middle, side(0), side(1)))
    }
    let count = boxes.len();
    let found = if depth >= MAX_SAH_DEPTH {
        None
    } else if count >= 128 {
        binned::<32>(boxes, indices, range)
    } else if count >= 24 {
        binned::<16>(boxes, indices, range)
    } else {
        binned::<4>(boxes, indices, range)
    };
    found.unwrap_or_else(|| {
        // Whole groups of four on the left.
        let middle = (count / 2)
            .next_multiple_of(MAX_PRIMS_PER_LEAF as usize)
            .min(count - 1);
        (
            middle,
            Range::of(&boxes[..middle]),
            Range::of(&boxes[middle..]),
        )
    })
}

/// Builds the subtree over `boxes` (whose primitive slots start at `offset`) into `nodes`,
/// its root at `at`; children are appended in pairs.
fn build_sequential(
    boxes: &mut [Aabb],
    indices: &mut [u32],
    offset: u32,
    range: Range,
    nodes: &mut Vec<Bvh2Node>,
    (at, depth): (usize, u32),
) {
    let count = boxes.len();
    if count <= MAX_PRIMS_PER_LEAF as usize {
        nodes[at] = Bvh2Node::new(range.bounds, count as u32, offset);
        return;
    }
    let (middle, left, right) = split(boxes, indices, &range, depth);
    let first = nodes.len();
    nodes.extend([Bvh2Node::default(); 2]);
    nodes[at] = Bvh2Node::new(range.bounds, 0, first as u32);
    let (left_boxes, right_boxes) = boxes.split_at_mut(middle);
    let (left_indices, right_indices) = indices.split_at_mut(middle);
    let below = depth + 1;
    build_sequential(
        left_boxes,
        left_indices,
        offset,
        left,
        nodes,
        (first, below),
    );
    let right_offset = offset + middle as u32;
    build_sequential(
        right_boxes,
        right_indices,
        right_offset,
        right,
        nodes,
        (first + 1, below),
    );
}

/// The top of the tree as built in parallel: a node list per range built sequentially (its
/// root at 0), joined by the splits above them.
enum Built {
    Subtree(Vec<Bvh2Node>),
    Split {
        bounds: Aabb,
        /// Nodes below this one.
        descendants: usize,
        children: Box<(Built, Built)>,
    },
}

impl Built {
    fn descendants(&self) -> usize {
        match self {
            Built::Subtree(nodes) => nodes.len() - 1,
            Built::Split { descendants, .. } => *descendants,
        }
    }
}

fn build_parallel(
    boxes: &mut [Aabb],
    indices: &mut [u32],
    (offset, depth): (u32, u32),
    range: Range,
) -> Built {
    let count = boxes.len();
    if count < SEQUENTIAL_BELOW {
        let mut nodes = Vec::with_capacity(2 * count.div_ceil(2));
        nodes.push(Bvh2Node::default());
        build_sequential(boxes, indices, offset, range, &mut nodes, (0, depth));
        return Built::Subtree(nodes);
    }
    let (middle, left, right) = split(boxes, indices, &range, depth);
    let (left_boxes, right_boxes) = boxes.split_at_mut(middle);
    let (left_indices, right_indices) = indices.split_at_mut(middle);
    let right_offset = offset + middle as u32;
    let children = rayon::join(
        || build_parallel(left_boxes, left_indices, (offset, depth + 1), left),
        || build_parallel(right_boxes, right_indices, (right_offset, depth + 1), right),
    );
    Built::Split {
        bounds: range.bounds,
        descendants: 2 + children.0.descendants() + children.1.descendants(),
        children: Box::new(children),
    }
}

/// Writes `built` with its root to `root` and its descendants to `below`, which starts at
/// node index `base`.
fn place(built: Built, root: &mut Bvh2Node, below: &mut [Bvh2Node], base: u32) {
    match built {
        Built::Subtree(nodes) => {
            let relocate = |node: Bvh2Node| {
                if node.is_leaf() {
                    node
                } else {
                    // Subtree node j >= 1 moves to base + j - 1.
                    Bvh2Node::new(*node.aabb(), 0, node.first_index + base - 1)
                }
            };
            *root = relocate(nodes[0]);
            for (slot, node) in below.iter_mut().zip(&nodes[1..]) {
                *slot = relocate(*node);
            }
        }
        Built::Split {
            bounds, children, ..
        } => {
            *root = Bvh2Node::new(bounds, 0, base);
            let (left, right) = *children;
            let (pair, rest) = below.split_at_mut(2);
            let (left_root, right_root) = pair.split_at_mut(1);
            let left_size = left.descendants();
            let (left_below, right_below) = rest.split_at_mut(left_size);
            let right_base = base + 2 + left_size as u32;
            rayon::join(
                || place(left, &mut left_root[0], left_below, base + 2),
                || place(right, &mut right_root[0], right_below, right_base),
            );
        }
    }
}

/// Builds the binary BVH over `boxes` (finite, at least one) by binned SAH, leaves of at most
/// [`MAX_PRIMS_PER_LEAF`] primitives, in parallel on the current rayon pool.
pub(crate) fn build_binned_sah(mut boxes: Vec<Aabb>) -> Bvh2 {
    debug_assert!(!boxes.is_empty());
    let mut indices: Vec<u32> = (0..boxes.len() as u32).into_par_iter().collect();
    let range = boxes
        .par_chunks(CHUNK)
        .map(Range::of)
        .reduce(Range::empty, Range::union);
    let built = build_parallel(&mut boxes, &mut indices, (0, 0), range);
    // `Bvh2::zeroed(n)` holds 2n - 1 nodes, zeroed lazily by the allocator; the tree has
    // 1 + 2k.
    let mut bvh2 = Bvh2::zeroed(1 + built.descendants() / 2);
    let (root, below) = bvh2.nodes.split_at_mut(1);
    place(built, &mut root[0], below, 1);
    bvh2.primitive_indices = indices;
    bvh2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::wide_bvh::{
        LeafAlignment, LeafSizing, TreeShape, collapse_to_wide, ploc_bvh2,
    };

    fn unit_box(x: f32, y: f32, z: f32) -> Aabb {
        Aabb {
            min: Vec3A::new(x, y, z),
            max: Vec3A::new(x + 1.0, y + 1.0, z + 1.0),
        }
    }

    /// The primitive ids of every leaf reached from the root, in walk order; asserts that
    /// every node's box holds its children's boxes and each leaf's box its primitives'.
    /// [`leaves`] with each leaf's ids sorted, and the leaves sorted.
    fn sorted_leaf_sets(bvh2: &Bvh2, boxes: &[Aabb]) -> Vec<Vec<u32>> {
        let mut sets: Vec<Vec<u32>> = leaves(bvh2, boxes)
            .into_iter()
            .map(|mut ids| {
                ids.sort();
                ids
            })
            .collect();
        sets.sort();
        sets
    }

    fn leaves(bvh2: &Bvh2, boxes: &[Aabb]) -> Vec<Vec<u32>> {
        let holds = |outer: &Aabb, inner: &Aabb| {
            outer.min.cmple(inner.min).all() && inner.max.cmple(outer.max).all()
        };
        let mut found = Vec::new();
        let mut stack = vec![0usize];
        while let Some(index) = stack.pop() {
            let node = &bvh2.nodes[index];
            if node.is_leaf() {
                let first = node.first_index as usize;
                let ids = bvh2.primitive_indices[first..first + node.prim_count as usize].to_vec();
                for &id in &ids {
                    assert!(holds(node.aabb(), &boxes[id as usize]), "leaf {index}");
                }
                found.push(ids);
                continue;
            }
            let first = node.first_index as usize;
            for child in [first, first + 1] {
                assert!(holds(node.aabb(), bvh2.nodes[child].aabb()), "node {index}");
                stack.push(child);
            }
        }
        found
    }

    #[test]
    fn the_threshold_is_the_last_coordinate_below_the_split_bin() {
        let next_up = |value: f32| {
            let bits = value.to_bits();
            f32::from_bits(if value >= 0.0 { bits + 1 } else { bits - 1 })
        };
        let ranges = [(-3.7f32, 12.25f32), (1.0e6, 1.0e6 + 0.5), (-1.0e-3, 2.0e-3)];
        for (low, high) in ranges {
            let centroids = Aabb {
                min: Vec3A::new(low, 0.0, -high),
                max: Vec3A::new(high, 1.0, -low),
            };
            let binning = Binning::<16>::new(&centroids);
            for axis in 0..3 {
                for position in 1..16 {
                    let threshold = binning.threshold(axis, position);
                    assert!(
                        binning.bin(threshold, axis) < position,
                        "{low} {axis} {position}"
                    );
                    assert!(
                        binning.bin(next_up(threshold), axis) >= position,
                        "{low} {axis} {position}: {threshold}"
                    );
                }
            }
        }
    }

    #[test]
    fn two_clusters_of_four_become_the_two_leaves_below_the_root() {
        // Interleaved in the input: even ids near x = 0, odd ids near x = 100.
        let boxes: Vec<Aabb> = (0..8)
            .map(|i| {
                let x = if i % 2 == 0 { 0.0 } else { 100.0 };
                unit_box(x + (i / 2) as f32 * 0.5, (i / 2) as f32, 0.0)
            })
            .collect();
        let bvh2 = build_binned_sah(boxes.clone());
        assert_eq!(bvh2.nodes.len(), 3);
        let sets = sorted_leaf_sets(&bvh2, &boxes);
        assert_eq!(sets, [vec![0, 2, 4, 6], vec![1, 3, 5, 7]]);
    }

    #[test]
    fn a_row_of_eight_boxes_splits_into_two_leaves_of_four() {
        // Splitting 4 | 4 tests two groups; 3 | 5 or 2 | 6 would test three.
        let boxes: Vec<Aabb> = (0..8).map(|i| unit_box(i as f32, 0.0, 0.0)).collect();
        let bvh2 = build_binned_sah(boxes.clone());
        let sets = sorted_leaf_sets(&bvh2, &boxes);
        assert_eq!(sets, [vec![0, 1, 2, 3], vec![4, 5, 6, 7]]);
    }

    #[test]
    fn every_primitive_is_in_exactly_one_leaf_of_at_most_four() {
        let mut seed = 7u64;
        let mut unit = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut cases: Vec<Vec<Aabb>> = [1, 2, 3, 4, 5, 17, 5000, 150_000]
            .into_iter()
            .map(|count| {
                (0..count)
                    .map(|_| {
                        let low = Vec3A::new(unit(), unit(), unit()) * 100.0;
                        let size = Vec3A::new(unit(), unit(), unit());
                        Aabb {
                            min: low,
                            max: low + size,
                        }
                    })
                    .collect()
            })
            .collect();
        // Identical boxes (no split separates their centroids) and a flat sheet.
        cases.push(vec![unit_box(1.0, 2.0, 3.0); 5000]);
        cases.push(
            (0..300)
                .map(|i| unit_box(0.0, (i % 20) as f32, (i / 20) as f32))
                .collect(),
        );
        for boxes in cases {
            let count = boxes.len();
            let bvh2 = build_binned_sah(boxes.clone());
            let found = leaves(&bvh2, &boxes);
            assert!(
                found.iter().all(|ids| (1..=4).contains(&ids.len())),
                "{count}"
            );
            let mut ids: Vec<u32> = found.concat();
            ids.sort();
            assert_eq!(ids, (0..count as u32).collect::<Vec<_>>(), "{count}");
            // Leaves of four where the primitives allow it.
            assert!(
                found.len() <= count / 3 + 1,
                "{count}: {} leaves",
                found.len()
            );
        }
    }

    #[test]
    fn centroids_over_many_scales_keep_the_tree_shallow() {
        // Centroids spread over 125 octaves, where binning may peel a few primitives off
        // level after level (the binned SAH itself stays at depth 33 here; a split peeling
        // one primitive per level reaches depth 1996 without the depth bound).
        let boxes: Vec<Aabb> = (0..2000)
            .map(|i| {
                let x = 2f32.powf(i as f32 / 16.0);
                Aabb {
                    min: Vec3A::new(x, 0.0, 0.0),
                    max: Vec3A::new(x * 1.01, 1.0, 1.0),
                }
            })
            .collect();
        let bvh2 = build_binned_sah(boxes.clone());
        let mut depth = vec![0u32; bvh2.nodes.len()];
        for index in 0..bvh2.nodes.len() {
            let node = bvh2.nodes[index];
            if !node.is_leaf() {
                let first = node.first_index as usize;
                depth[first] = depth[index] + 1;
                depth[first + 1] = depth[index] + 1;
            }
        }
        let deepest = depth.iter().max().copied().unwrap_or(0);
        // 64 levels of SAH, then halving 2000 primitives at most 11 times.
        assert!(deepest <= 75, "{deepest}");
        let found = leaves(&bvh2, &boxes);
        assert_eq!(found.iter().map(Vec::len).sum::<usize>(), 2000);
    }

    #[test]
    fn the_wide_tree_over_a_height_field_costs_less_than_from_ploc() {
        // 120 x 120 cells of two triangles over a bumpy surface, in mesh order.
        let cells = 120;
        let height = |x: usize, y: usize| ((x as f32 * 0.3).sin() + (y as f32 * 0.2).cos()) * 2.0;
        let corner = |x: usize, y: usize| Vec3A::new(x as f32, y as f32, height(x, y));
        let triangle = |a: Vec3A, b: Vec3A, c: Vec3A| Aabb {
            min: a.min(b).min(c),
            max: a.max(b).max(c),
        };
        let mut boxes = Vec::new();
        for y in 0..cells {
            for x in 0..cells {
                let [a, b, c, d] =
                    [(x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1)].map(|(x, y)| corner(x, y));
                boxes.push(triangle(a, b, c));
                boxes.push(triangle(a, c, d));
            }
        }
        let bounds = boxes
            .iter()
            .fold(Aabb::empty(), |all, aabb| all.union(aabb));
        let bounds = (bounds.min.into(), bounds.max.into());
        let cost = |bvh2: &Bvh2| {
            let (nodes, _) = collapse_to_wide(bvh2, LeafSizing::Whole, LeafAlignment::Group);
            TreeShape::of(&nodes, bounds)
        };
        let binned = cost(&build_binned_sah(boxes.clone()));
        let ploc = cost(&ploc_bvh2(&boxes));
        assert!(
            binned.node_cost < 0.9 * ploc.node_cost && binned.nodes < ploc.nodes,
            "{binned:?} vs {ploc:?}"
        );
        // Fuller leaves: fewer of them.
        assert!(
            binned.leaves * 10 < ploc.leaves * 9,
            "{binned:?} vs {ploc:?}"
        );
    }
}
