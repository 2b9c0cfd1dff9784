//! A render whose worker stops on an internal error (a panic on the device's thread) still
//! finishes: the application's wait returns, the status callback says the image is incomplete,
//! and the next render of the frame is whole again. Its own test binary, since the failure is
//! injected through a process-wide switch.

mod common;
use common::*;

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use cavetrace::render::frame::FAIL_NEXT_TILE;

#[test]
fn a_render_that_loses_a_worker_finishes_and_says_its_image_is_incomplete() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let triangle = triangle_geometry(dev, &[[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]]);
    let surface = matte_surface(dev, triangle, [1.0, 0.5, 0.25]);
    let world = world_of(dev, &[surface]);
    let camera = perspective_camera(dev, [0.0, 0.0, 3.0], [0.0, 0.0, -1.0], 0.8);
    let renderer = plain_renderer(dev, "fast");
    // Several tiles of 32×32 pixels, so that the failed one leaves others untraced.
    let frame = frame_for(dev, world, camera, renderer, [96, 96]);
    let whole = render_channel::<f32>(dev, frame, "channel.depth").0;
    assert!(log.errors().is_empty());

    FAIL_NEXT_TILE.store(true, Ordering::SeqCst);
    anariRenderFrame(dev, frame);
    // Waited for by polling, so that a render that never finishes fails the test, not hangs it.
    let started = Instant::now();
    while anariFrameReady(dev, frame, ANARI_NO_WAIT) == 0 {
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "the render never finished after its worker failed"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(!FAIL_NEXT_TILE.load(Ordering::SeqCst), "no tile was taken");
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    let (code, text) = &errors[0];
    assert_eq!(*code, ANARI_STATUS_UNKNOWN_ERROR);
    assert!(
        text.starts_with("anariRenderFrame: a render thread stopped on an internal error")
            && text.contains("FAIL_NEXT_TILE")
            && text.contains("incomplete"),
        "{text}"
    );

    // The frame renders whole again.
    let again = render_channel::<f32>(dev, frame, "channel.depth").0;
    assert_eq!(again.len(), whole.len());
    assert!(
        again
            .iter()
            .zip(&whole)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    assert!(log.errors().is_empty());
    release_all(dev, &[frame, renderer, camera, world, surface, triangle]);
    release_device(lib, dev);
}
