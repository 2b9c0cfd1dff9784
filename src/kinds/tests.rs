//! The table as a whole, and what needs a device serving every kind.

use glam::Vec3;

use super::*;
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::light::Light;

#[test]
fn every_spec_is_unique_and_every_parameter_has_types() {
    let specs = KINDS.specs();
    for (i, a) in specs.iter().enumerate() {
        for b in &specs[i + 1..] {
            assert!(
                !(a.kind == b.kind && a.subtype == b.subtype),
                "duplicate spec {} '{}'",
                a.kind,
                a.subtype
            );
        }
        for p in a.params {
            assert!(!p.types.is_empty(), "{} has no types", p.name);
            for t in p.types {
                assert!(is_valid(*t), "{}: bad type {t}", p.name);
            }
        }
    }
}

static REPORTED: std::sync::Mutex<Vec<(i32, String)>> = std::sync::Mutex::new(Vec::new());

unsafe extern "C" fn remember(
    _: *const std::ffi::c_void,
    _: *mut std::ffi::c_void,
    _: *mut std::ffi::c_void,
    _: ANARIDataType,
    _: crate::device::status::ANARIStatusSeverity,
    code: crate::device::status::ANARIStatusCode,
    message: *const std::ffi::c_char,
) {
    // SAFETY: the device passes a valid C string.
    let text = unsafe { std::ffi::CStr::from_ptr(message) }.to_string_lossy();
    REPORTED.lock().unwrap().push((code, text.into_owned()));
}

#[test]
fn commit_reports_bad_values_and_build_ignores_them() {
    use crate::device::IncomingValue;
    let device = Device::new(&KINDS, Some(remember), 0);
    let handle = device.new_object("anariNewLight", ANARI_LIGHT, "point");
    let set = |name: &str, value: f32| {
        let bytes = value.to_ne_bytes().to_vec();
        device.set_parameter(
            "anariSetParameter",
            handle,
            name,
            ANARI_FLOAT32,
            IncomingValue::Data(bytes),
        );
    };
    set("power", -2.0);
    set("radius", f32::NAN);
    set("radiance", 3.0);
    device.commit("anariCommitParameters", handle);
    let object = device.lookup(handle).unwrap();
    REPORTED.lock().unwrap().clear();
    light::commit(&device, &object);
    let reported = std::mem::take(&mut *REPORTED.lock().unwrap());
    let has = |code: i32, words: &[&str]| {
        reported
            .iter()
            .any(|(c, t)| *c == code && words.iter().all(|w| t.contains(w)))
    };
    assert!(
        has(
            ANARI_STATUS_INVALID_ARGUMENT,
            &["light 'point'", "'power'", "-2"]
        ),
        "{reported:?}"
    );
    assert!(
        has(ANARI_STATUS_INVALID_ARGUMENT, &["'radius'", "NaN"]),
        "{reported:?}"
    );
    // The radius is invalid, so the light has no extent and its radiance is unused.
    assert!(
        has(
            crate::device::status::ANARI_STATUS_NO_ERROR,
            &["'radiance'", "'radius' > 0"]
        ),
        "{reported:?}"
    );
    assert_eq!(reported.len(), 3, "{reported:?}");
    assert_eq!(
        Light::build(&object),
        Some(Light::Point {
            position: Vec3::ZERO,
            intensity: Vec3::ONE,
            radius: 0.0,
            visible: true,
        })
    );
    device.release("anariRelease", handle);
}
