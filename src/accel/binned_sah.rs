//! A binned surface-area-heuristic (SAH) builder of the binary BVH for whole leaves
//! (`LeafSizing::Whole`: triangles and quads).
//!
//! Top-down: each range of primitives is split where the surface area heuristic is least,
//! found by binning the doubled centroids (box minimum plus maximum) into bins along each of
//! the three axes. A leaf holds at most [`MAX_PRIMS_PER_LEAF`] primitives and is tested as one
//! group whatever its count, so a side of a split costs its half area times the groups of four
//! it needs (as Embree sizes its leaves by its block size): splits fill leaves toward four.
//!
//! The primitives' boxes are copied once and partitioned in place beside their indices; the
//! ranges below [`SEQUENTIAL_BELOW`] primitives are built by one task each into a node list
//! of their own, the ranges above by `rayon::join` (binning the largest in parallel chunks),
//! and [`place`] stitches the lists into obvhs' layout (children of a node side by side).

use glam::{UVec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use rayon::iter::{IntoParallelIterator, IntoParallelRefIterator, ParallelIterator};
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

    /// The bins of `aabb` along each axis (`B` is a power of two: the mask keeps the index in
    /// range for the compiler; the saturating conversion and `min` already do for values).
    fn bins(&self, aabb: &Aabb) -> UVec3 {
        let position = (aabb.min + aabb.max - self.origin) * self.scale;
        position.as_uvec3().min(UVec3::splat(B as u32 - 1)) & UVec3::splat(B as u32 - 1)
    }
}

/// Per axis and bin: the union of the primitive boxes and their count.
struct Bins<const B: usize> {
    lower: [[Vec3A; B]; 3],
    upper: [[Vec3A; B]; 3],
    counts: [[u32; B]; 3],
}

/// Where a range is split: primitives whose bin along `axis` is below `position` go left.
#[derive(Clone, Copy)]
struct Split {
    axis: usize,
    position: u32,
}

impl<const B: usize> Bins<B> {
    fn empty() -> Self {
        Bins {
            lower: [[Vec3A::splat(f32::MAX); B]; 3],
            upper: [[Vec3A::splat(f32::MIN); B]; 3],
            counts: [[0; B]; 3],
        }
    }

    fn add(&mut self, binning: &Binning<B>, boxes: &[Aabb]) {
        for aabb in boxes {
            let bins = binning.bins(aabb);
            for axis in 0..3 {
                let bin = bins[axis] as usize;
                self.lower[axis][bin] = self.lower[axis][bin].min(aabb.min);
                self.upper[axis][bin] = self.upper[axis][bin].max(aabb.max);
                self.counts[axis][bin] += 1;
            }
        }
    }

    fn merge(mut self, other: Self) -> Self {
        for axis in 0..3 {
            for bin in 0..B {
                self.lower[axis][bin] = self.lower[axis][bin].min(other.lower[axis][bin]);
                self.upper[axis][bin] = self.upper[axis][bin].max(other.upper[axis][bin]);
                self.counts[axis][bin] += other.counts[axis][bin];
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
        let mut best: Option<(f32, Split)> = None;
        for axis in 0..3 {
            let (lower, upper, counts) = (&self.lower[axis], &self.upper[axis], &self.counts[axis]);
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
                let cost =
                    side_cost(half_area(left_lower, left_upper), left_count) + right_costs[position];
                if best.is_none_or(|(least, _)| cost < least) {
                    let position = position as u32;
                    best = Some((cost, Split { axis, position }));
                }
            }
        }
        best.map(|(_, split)| split)
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
/// returns their count and the ranges of both sides.
fn partition(
    boxes: &mut [Aabb],
    indices: &mut [u32],
    goes_left: impl Fn(&Aabb) -> bool,
) -> (usize, Range, Range) {
    let (mut left, mut right) = (Range::empty(), Range::empty());
    let (mut begin, mut end) = (0, boxes.len());
    loop {
        while begin < end && goes_left(&boxes[begin]) {
            left.add(&boxes[begin]);
            begin += 1;
        }
        while begin < end && !goes_left(&boxes[end - 1]) {
            right.add(&boxes[end - 1]);
            end -= 1;
        }
        if begin == end {
            return (begin, left, right);
        }
        // boxes[begin] goes right, boxes[end - 1] left.
        right.add(&boxes[begin]);
        left.add(&boxes[end - 1]);
        boxes.swap(begin, end - 1);
        indices.swap(begin, end - 1);
        begin += 1;
        end -= 1;
    }
}

/// Splits a range of more than one primitive in two (both sides non-empty): at the binned
/// SAH's best split, else (all centroids in one bin) in the middle.
fn split(boxes: &mut [Aabb], indices: &mut [u32], range: &Range) -> (usize, Range, Range) {
    fn binned<const B: usize>(
        boxes: &mut [Aabb],
        indices: &mut [u32],
        range: &Range,
    ) -> Option<(usize, Range, Range)> {
        let (binning, split) = find_split::<B>(boxes, range)?;
        Some(partition(boxes, indices, |aabb| {
            binning.bins(aabb)[split.axis] < split.position
        }))
    }
    let count = boxes.len();
    let found = if count >= 128 {
        binned::<32>(boxes, indices, range)
    } else if count >= 24 {
        binned::<16>(boxes, indices, range)
    } else {
        binned::<8>(boxes, indices, range)
    };
    found.unwrap_or_else(|| {
        let middle = count / 2;
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
    at: usize,
) {
    let count = boxes.len();
    if count <= MAX_PRIMS_PER_LEAF as usize {
        nodes[at] = Bvh2Node::new(range.bounds, count as u32, offset);
        return;
    }
    let (middle, left, right) = split(boxes, indices, &range);
    let first = nodes.len();
    nodes.extend([Bvh2Node::default(); 2]);
    nodes[at] = Bvh2Node::new(range.bounds, 0, first as u32);
    let (left_boxes, right_boxes) = boxes.split_at_mut(middle);
    let (left_indices, right_indices) = indices.split_at_mut(middle);
    build_sequential(left_boxes, left_indices, offset, left, nodes, first);
    let right_offset = offset + middle as u32;
    build_sequential(right_boxes, right_indices, right_offset, right, nodes, first + 1);
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

fn build_parallel(boxes: &mut [Aabb], indices: &mut [u32], offset: u32, range: Range) -> Built {
    let count = boxes.len();
    if count < SEQUENTIAL_BELOW {
        let mut nodes = Vec::with_capacity(2 * count.div_ceil(2));
        nodes.push(Bvh2Node::default());
        build_sequential(boxes, indices, offset, range, &mut nodes, 0);
        return Built::Subtree(nodes);
    }
    let (middle, left, right) = split(boxes, indices, &range);
    let (left_boxes, right_boxes) = boxes.split_at_mut(middle);
    let (left_indices, right_indices) = indices.split_at_mut(middle);
    let right_offset = offset + middle as u32;
    let children = rayon::join(
        || build_parallel(left_boxes, left_indices, offset, left),
        || build_parallel(right_boxes, right_indices, right_offset, right),
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
pub(crate) fn build_binned_sah(boxes: &[Aabb]) -> Bvh2 {
    debug_assert!(!boxes.is_empty());
    let mut work: Vec<Aabb> = boxes.par_iter().copied().collect();
    let mut indices: Vec<u32> = (0..boxes.len() as u32).into_par_iter().collect();
    let range = work
        .par_chunks(CHUNK)
        .map(Range::of)
        .reduce(Range::empty, Range::union);
    let built = build_parallel(&mut work, &mut indices, 0, range);
    let mut nodes = vec![Bvh2Node::default(); 1 + built.descendants()];
    let (root, below) = nodes.split_at_mut(1);
    place(built, &mut root[0], below, 1);
    Bvh2 {
        nodes,
        primitive_indices: indices,
        ..Bvh2::default()
    }
}
