//! Traversal counters for measuring trees (`--features kernel-counters`; without the feature
//! every call is empty and nothing is counted). Per thread: the bench sums what each worker
//! took.
//!
//! With the feature, single rays over triangles take the generic walk
//! (`walk::traverse_with`, same visiting order and hits as the per-octant walk of
//! `single_ray`), counting its inner nodes, leaves and triangle lanes; the frustum walk counts
//! the nodes it pops (once per packet) and, per leaf, the groups of four rays and the rays that
//! test it.

/// What the walks of one thread did since the last [`take`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalCounts {
    /// Single rays traced.
    pub rays: u64,
    /// Inner nodes whose child boxes a single ray tested.
    pub nodes: u64,
    /// Leaves (triangle groups) a single ray tested.
    pub leaves: u64,
    /// Triangles in those leaves.
    pub triangles: u64,
    /// Frustum packets traced, and the rays in them.
    pub packets: u64,
    pub packet_rays: u64,
    /// Inner nodes a frustum packet popped and culled its children at.
    pub packet_nodes: u64,
    /// Leaf tests of a group of four rays, and the rays (lanes) they tested.
    pub packet_leaf_groups: u64,
    pub packet_leaf_rays: u64,
    /// Triangles tested, summed over rays.
    pub packet_triangle_rays: u64,
}

impl std::ops::AddAssign for TraversalCounts {
    fn add_assign(&mut self, other: TraversalCounts) {
        self.rays += other.rays;
        self.nodes += other.nodes;
        self.leaves += other.leaves;
        self.triangles += other.triangles;
        self.packets += other.packets;
        self.packet_rays += other.packet_rays;
        self.packet_nodes += other.packet_nodes;
        self.packet_leaf_groups += other.packet_leaf_groups;
        self.packet_leaf_rays += other.packet_leaf_rays;
        self.packet_triangle_rays += other.packet_triangle_rays;
    }
}

/// Whether counting is compiled in.
pub const ENABLED: bool = cfg!(feature = "kernel-counters");

#[cfg(feature = "kernel-counters")]
thread_local! {
    static COUNTS: std::cell::Cell<TraversalCounts> =
        const { std::cell::Cell::new(TraversalCounts {
            rays: 0, nodes: 0, leaves: 0, triangles: 0, packets: 0, packet_rays: 0,
            packet_nodes: 0, packet_leaf_groups: 0, packet_leaf_rays: 0,
            packet_triangle_rays: 0,
        }) };
}

/// This thread's counts since the last call (all zero without the feature).
pub fn take() -> TraversalCounts {
    #[cfg(feature = "kernel-counters")]
    return COUNTS.with(|counts| counts.take());
    #[cfg(not(feature = "kernel-counters"))]
    TraversalCounts::default()
}

/// Adds to this thread's counts (compiled out without the feature).
#[inline(always)]
pub(crate) fn add(update: impl FnOnce(&mut TraversalCounts)) {
    #[cfg(feature = "kernel-counters")]
    COUNTS.with(|counts| {
        let mut value = counts.get();
        update(&mut value);
        counts.set(value);
    });
    #[cfg(not(feature = "kernel-counters"))]
    let _ = update;
}
