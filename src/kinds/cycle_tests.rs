//! Objects that refer to each other are freed when the device is released.

use std::sync::Arc;

use crate::device::datatype::*;
use crate::device::{Device, IncomingValue};

#[test]
fn device_release_frees_objects_that_refer_to_each_other() {
    let device = Device::new(&super::KINDS, None, 0);
    let first = device.new_object("test", ANARI_GEOMETRY, "triangle");
    let second = device.new_object("test", ANARI_GEOMETRY, "triangle");
    // A parameter naming its own object, and two objects naming each other (found by the C API
    // fuzzer: each such cycle leaked its objects after the device's release).
    let set = |on: usize, to: usize| {
        device.set_parameter("test", on, "x", ANARI_GEOMETRY, IncomingValue::Handle(to));
        device.commit("test", on);
    };
    set(first, first);
    set(first, second);
    set(second, first);
    let watched = [first, second].map(|h| Arc::downgrade(&device.lookup(h).unwrap()));
    device.release("test", first);
    device.release("test", second);
    assert!(
        watched.iter().all(|w| w.upgrade().is_some()),
        "the cycle keeps them alive"
    );
    assert!(device.release("test", device.handle));
    for object in &watched {
        assert!(object.upgrade().is_none(), "an object outlived its device");
    }
}
