//! Exact ties between leaves (the same triangle several times, in different leaves): the hit
//! record then depends on which leaf the walk tests last, so only walks that visit a node's
//! children in the node's own order (`WideNode::orders`) agree.

use super::*;
use crate::accel::isa::{self, Isa};
use crate::accel::wide_bvh::IDENTITY_ORDERS;

/// A bumpy grid whose every triangle is there five times (five ids, one triangle; more than a
/// leaf holds): every hit is a tie at the same `t`, between lanes of one group or between
/// leaves.
fn repeated_grid(cells: u32) -> GeometryPrims {
    let GeometryPrims::Triangles { positions, indices } = bumpy_grid(cells).1 else {
        unreachable!("a grid of triangles")
    };
    let indices = indices.iter().flat_map(|&triangle| [triangle; 5]).collect();
    GeometryPrims::Triangles { positions, indices }
}

#[test]
fn ties_between_leaves_resolve_alike_on_every_walk() {
    let geometry = Arc::new(GeometryBvh::build(repeated_grid(16)));
    // The grid spreads in x and y only: its nodes take orders other than the x, y, z one, so a
    // walk visiting slots `i ^ octant` would test tied leaves in another order.
    let reordered = geometry
        .wide_nodes()
        .iter()
        .filter(|node| node.orders != IDENTITY_ORDERS)
        .count();
    assert!(reordered > 0, "no node with its own order");
    let scene = SceneBvh::build(vec![identity_instance(vec![geometry])]);
    let mut rng = Rng::new(2811);
    // Cameras above the grid looking down from several sides (every octant with z < 0), in
    // 8x8 tiles for the packets.
    let mut rays = Vec::new();
    for (x, y) in [
        (-4.0, -4.0),
        (20.0, -4.0),
        (-4.0, 20.0),
        (20.0, 20.0),
        (8.0, 8.0),
    ] {
        rays.extend(camera_tiles(
            &mut rng,
            vec3(x, y, 9.0),
            vec3(8.0, 8.0, 0.0),
            48,
        ));
    }
    let baseline: Vec<Option<SceneHit>> = isa::on_path(Isa::Baseline, || {
        rays.iter().map(|ray| scene.intersect(ray)).collect()
    });
    let hits = baseline.iter().filter(|hit| hit.is_some()).count();
    assert!(
        hits > rays.len() / 5,
        "only {hits} of {} rays hit",
        rays.len()
    );
    let compare = |name: &str, found: &[Option<SceneHit>]| {
        let differing: Vec<usize> = (0..rays.len())
            .filter(|&i| format!("{:?}", baseline[i]) != format!("{:?}", found[i]))
            .collect();
        assert!(
            differing.is_empty(),
            "{name}: {} of {} rays differ from the baseline's single rays, e.g. {:?}",
            differing.len(),
            rays.len(),
            differing.first().map(|&i| (rays[i], baseline[i], found[i]))
        );
    };
    for isa in isa::test_paths() {
        isa::on_path(isa, || {
            let single: Vec<_> = rays.iter().map(|ray| scene.intersect(ray)).collect();
            compare(&format!("single rays, {isa:?}"), &single);
            // The generic walk (taken by rays that may hit before their origin; none here).
            let generic: Vec<_> = rays
                .iter()
                .map(|ray| {
                    let mut ray = *ray;
                    if ray.t_min == 0.0 {
                        ray.t_min = -1.0e-30;
                    }
                    scene.intersect(&ray)
                })
                .collect();
            compare(&format!("the generic walk, {isa:?}"), &generic);
            let mut scratch = PacketScratch::new();
            let mut packets = vec![None; rays.len()];
            for (chunk, found) in rays.chunks(64).zip(packets.chunks_mut(64)) {
                scene.intersect_packet_with(&mut scratch, chunk, found);
            }
            compare(&format!("packets, {isa:?}"), &packets);
            let mut eights = vec![None; rays.len()];
            for (eight, found) in rays.chunks_exact(8).zip(eights.chunks_exact_mut(8)) {
                scene.intersect8(eight.try_into().unwrap(), found.try_into().unwrap());
            }
            compare(&format!("eights, {isa:?}"), &eights);
        });
    }
}
