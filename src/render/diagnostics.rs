//! Commit diagnostics: when a frame renders, every object it uses (the frame, its world,
//! camera and renderer, and everything they reach through their committed parameters:
//! surfaces, geometries, materials, samplers, lights, instances, groups, volumes, fields) is
//! checked for parameters set or unset after its last commit, and for never having been
//! committed. Each is a legal program that is almost always a mistake (the render uses the
//! committed state), so it is a WARNING, reported once per object and change.

use std::collections::HashSet;
use std::sync::Arc;

use crate::device::Device;
use crate::device::object::{Object, Pending};
use crate::device::params::ParamValue;
use crate::render::frame::FrameState;
use crate::render::renderer::RendererSettings;
use crate::scene::material::Input;
use crate::scene::world::SceneSnapshot;

/// Warns, once until it changes, that a default renderer with no ambient light renders a world
/// without lights: its surfaces come out black, which looks like a broken program.
pub fn report_unlit(
    device: &Device,
    frame: &Object,
    state: &FrameState,
    settings: &RendererSettings,
    scene: &SceneSnapshot,
) {
    let mut surfaces = scene.instances.iter().flat_map(|i| &i.surfaces).peekable();
    let has_surfaces = surfaces.peek().is_some();
    // A material whose emission is not a constant zero may light the image itself.
    let emits = surfaces.any(|s| match &s.material.emissive {
        Input::Constant(v) => v.truncate() != glam::Vec3::ZERO,
        _ => true,
    });
    let unlit = !settings.fast
        && settings.ambient == glam::Vec3::ZERO
        && scene.lights.is_empty()
        && has_surfaces
        && !emits;
    if state.first_unlit_render(unlit) {
        device.warning(
            Some(frame),
            format!(
                "anariRenderFrame: {}: renderer 'default' has 'ambientRadiance' 0 and the world \
                 has no lights, so its surfaces are unlit and render black (apart from emission \
                 and reflections of the background); add a light to the world's 'light' array \
                 or set the renderer's 'ambientRadiance' > 0",
                frame.describe()
            ),
        );
    }
}

/// Walks what `frame` uses and warns about uncommitted changes and uncommitted objects.
pub fn report_uncommitted(device: &Device, frame: &Object) {
    check(device, frame);
    let mut seen = HashSet::new();
    seen.insert(frame as *const Object as usize);
    let mut stack = vec![frame.committed()];
    while let Some(params) = stack.pop() {
        for (_, value) in params.iter() {
            let ParamValue::Object { object: used, .. } = value else {
                continue;
            };
            // Arrays are not committed; the objects in an array of handles are used.
            let reached = match &used.array {
                Some(store) => store.objects(),
                None => vec![Arc::clone(used)],
            };
            for next in reached {
                if seen.insert(Arc::as_ptr(&next) as usize) {
                    check(device, &next);
                    stack.push(next.committed());
                }
            }
        }
    }
}

fn check(device: &Device, object: &Object) {
    // Unknown subtypes were reported at creation and are ignored when rendering.
    if object.spec.is_none() {
        return;
    }
    let what = object.describe();
    if object.commit_count() == 0 {
        if !object.first_report_of_no_commit() {
            return;
        }
        device.warning(
            Some(object),
            format!(
                "anariRenderFrame: {what} is used by this frame but was never committed; this \
                 render ignores its parameters (call anariCommitParameters on it)"
            ),
        );
        return;
    }
    let changes = object.unreported_changes();
    if changes.is_empty() {
        return;
    }
    let list = |pending: Pending| -> Vec<String> {
        changes
            .iter()
            .filter(|(_, p)| *p == pending)
            .map(|(name, _)| format!("'{name}'"))
            .collect()
    };
    let (set, unset) = (list(Pending::Set), list(Pending::Unset));
    let mut parts = Vec::new();
    if !set.is_empty() {
        parts.push(format!("{} set", set.join(", ")));
    }
    if !unset.is_empty() {
        parts.push(format!("{} unset", unset.join(", ")));
    }
    device.warning(
        Some(object),
        format!(
            "anariRenderFrame: {what}: {} after the last commit; this render uses the committed \
             state (call anariCommitParameters on it)",
            parts.join(" and ")
        ),
    );
}
