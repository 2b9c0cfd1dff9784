//! cavetrace as the Khronos ANARI SDK loads it. The test plays the SDK front end (`libanari.so`):
//! it dlopens `libanari_library_cavetrace.so` (RTLD_LAZY | RTLD_LOCAL), calls
//! `anari_library_cavetrace_new_library`, and drives the returned objects only through their
//! vtables: read the first word, call slot N with the signature of the SDK's
//! `anari::LibraryImpl` / `anari::DeviceImpl` (SDK 0.14–0.17). Slot numbers and layouts below
//! are the SDK's, so any layout change in `cavetrace::sdk` fails here.
//!
//! Before that, a copy of libcavetrace.so is loaded RTLD_GLOBAL as a decoy: like the front end's
//! own `anari*` functions, its exported `anari*` symbols then sit in the global scope, so any call
//! the library under test made to an exported `anari*` symbol would land in the decoy (a separate
//! registry that knows none of its handles) and fail.

use std::ffi::{CStr, CString, c_char, c_int, c_void};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use libloading::os::unix::{Library, RTLD_GLOBAL, RTLD_LAZY, RTLD_LOCAL, RTLD_NOW};

// ANARI values from anari.h (ANARI 1.0).
const ANARI_DATA_TYPE: i32 = 100;
const ANARI_STRING: i32 = 101;
const ANARI_VOID_POINTER: i32 = 102;
const ANARI_BOOL: i32 = 103;
const ANARI_STRING_LIST: i32 = 150;
const ANARI_PARAMETER_LIST: i32 = 152;
const ANARI_STATUS_CALLBACK: i32 = 202;
const ANARI_FRAME_COMPLETION_CALLBACK: i32 = 203;
const ANARI_LIBRARY: i32 = 500;
const ANARI_DEVICE: i32 = 501;
const ANARI_ARRAY1D: i32 = 504;
const ANARI_ARRAY2D: i32 = 505;
const ANARI_ARRAY3D: i32 = 506;
const ANARI_CAMERA: i32 = 507;
const ANARI_FRAME: i32 = 508;
const ANARI_GEOMETRY: i32 = 509;
const ANARI_MATERIAL: i32 = 513;
const ANARI_RENDERER: i32 = 514;
const ANARI_SURFACE: i32 = 515;
const ANARI_WORLD: i32 = 519;
const ANARI_INT32: i32 = 1016;
const ANARI_UINT32: i32 = 1020;
const ANARI_UINT32_VEC2: i32 = 1021;
const ANARI_FLOAT32: i32 = 1068;
const ANARI_FLOAT32_VEC3: i32 = 1070;
const ANARI_FLOAT32_VEC4: i32 = 1071;
const ANARI_FLOAT32_BOX3: i32 = 2010;
const ANARI_SEVERITY_ERROR: i32 = 2;
const ANARI_SEVERITY_WARNING: i32 = 3;
const ANARI_STATUS_INVALID_ARGUMENT: i32 = 2;
const ANARI_STATUS_INVALID_OPERATION: i32 = 3;
const ANARI_WAIT: u32 = 1;

/// `anari::LibraryImpl` slots.
mod library_slot {
    pub const DELETING_DESTRUCTOR: usize = 1;
    pub const NEW_DEVICE: usize = 2;
    pub const NEW_INITIALIZED_DEVICE: usize = 3;
    pub const GET_DEVICE_EXTENSIONS: usize = 4;
    pub const GET_DEVICE_SUBTYPES: usize = 5;
    pub const LOAD_MODULE: usize = 6;
}

/// `anari::DeviceImpl` slots.
mod device_slot {
    pub const NEW_ARRAY_1D: usize = 0;
    pub const NEW_ARRAY_2D: usize = 1;
    pub const NEW_ARRAY_3D: usize = 2;
    pub const NEW_GEOMETRY: usize = 3;
    pub const NEW_MATERIAL: usize = 4;
    pub const NEW_SAMPLER: usize = 5;
    pub const NEW_SURFACE: usize = 6;
    pub const NEW_WORLD: usize = 12;
    pub const NEW_CAMERA: usize = 13;
    pub const NEW_RENDERER: usize = 14;
    pub const NEW_FRAME: usize = 15;
    pub const SET_PARAMETER: usize = 16;
    pub const UNSET_PARAMETER: usize = 17;
    pub const UNSET_ALL_PARAMETERS: usize = 18;
    pub const MAP_PARAMETER_ARRAY_1D: usize = 19;
    pub const UNMAP_PARAMETER_ARRAY: usize = 22;
    pub const COMMIT_PARAMETERS: usize = 23;
    pub const RELEASE: usize = 24;
    pub const RETAIN: usize = 25;
    pub const MAP_ARRAY: usize = 26;
    pub const UNMAP_ARRAY: usize = 27;
    pub const GET_PROPERTY: usize = 28;
    pub const GET_OBJECT_SUBTYPES: usize = 29;
    pub const GET_OBJECT_INFO: usize = 30;
    pub const GET_PARAMETER_INFO: usize = 31;
    pub const FRAME_BUFFER_MAP: usize = 32;
    pub const FRAME_BUFFER_UNMAP: usize = 33;
    pub const RENDER_FRAME: usize = 34;
    pub const FRAME_READY: usize = 35;
    pub const DISCARD_FRAME: usize = 36;
    pub const NEW_OBJECT: usize = 37;
    pub const GET_PROC_ADDRESS: usize = 38;
    pub const DELETING_DESTRUCTOR: usize = 40;
}

type Handle = *mut c_void;
type StatusCallback =
    unsafe extern "C" fn(*const c_void, Handle, Handle, i32, i32, i32, *const c_char);
type CompletionCallback = unsafe extern "C" fn(*const c_void, Handle, Handle);

/// Calls slot `$slot` of `$object`'s vtable as `fn(object, args…) -> ret`, as C++ does.
macro_rules! virtual_call {
    ($object:expr, $slot:expr, ($($arg:ty),*) $(-> $ret:ty)?; $($value:expr),*) => {{
        let object: Handle = $object;
        let address = slot_address(object, $slot);
        // SAFETY: the slot holds a function of this signature (the SDK's declaration).
        let function: unsafe extern "C" fn(Handle $(, $arg)*) $(-> $ret)? =
            unsafe { std::mem::transmute::<usize, _>(address) };
        // SAFETY: arguments follow the ANARI API contract of the matching anari* function.
        unsafe { function(object $(, $value)*) }
    }};
}

/// Word `slot` of the vtable the object's first word points at.
fn slot_address(object: Handle, slot: usize) -> usize {
    assert!(!object.is_null(), "virtual call on NULL");
    // SAFETY: `object` is a live library or device object whose first word is its vtable.
    unsafe {
        let vtable = *(object as *const *const usize);
        let address = *vtable.add(slot);
        assert_ne!(address, 0, "slot {slot} is empty");
        address
    }
}

fn word_at(object: Handle, offset: usize) -> usize {
    // SAFETY: reads a pointer-sized member of a live object at an aligned offset.
    unsafe { *((object as *const u8).add(offset) as *const usize) }
}

fn c(s: &str) -> CString {
    CString::new(s).unwrap()
}

fn string_list(list: *const *const c_char) -> Vec<String> {
    assert!(!list.is_null());
    let mut out = Vec::new();
    // SAFETY: a NULL-terminated array of C strings, per the API.
    unsafe {
        let mut entry = list;
        while !(*entry).is_null() {
            out.push(CStr::from_ptr(*entry).to_string_lossy().into_owned());
            entry = entry.add(1);
        }
    }
    out
}

#[derive(Clone, Debug)]
struct Message {
    /// Which callback received it: 1 = the library's default, 2 = a device parameter callback.
    callback: u32,
    device: usize,
    source: usize,
    source_type: i32,
    severity: i32,
    code: i32,
    text: String,
}

#[derive(Default)]
struct Log(Mutex<Vec<Message>>);

impl Log {
    fn take(&self) -> Vec<Message> {
        std::mem::take(&mut self.0.lock().unwrap())
    }
    fn errors(&self) -> Vec<Message> {
        self.take()
            .into_iter()
            .filter(|m| m.severity <= ANARI_SEVERITY_ERROR)
            .collect()
    }
}

fn record(
    callback: u32,
    user: *const c_void,
    device: Handle,
    source: Handle,
    args: (i32, i32, i32),
    message: *const c_char,
) {
    // SAFETY: the tests pass a live Log as user data; the device passes a C string.
    let log = unsafe { &*(user as *const Log) };
    let text = unsafe { CStr::from_ptr(message) }
        .to_string_lossy()
        .into_owned();
    log.0.lock().unwrap().push(Message {
        callback,
        device: device as usize,
        source: source as usize,
        source_type: args.0,
        severity: args.1,
        code: args.2,
        text,
    });
}

unsafe extern "C" fn default_callback(
    user: *const c_void,
    device: Handle,
    source: Handle,
    source_type: i32,
    severity: i32,
    code: i32,
    message: *const c_char,
) {
    record(
        1,
        user,
        device,
        source,
        (source_type, severity, code),
        message,
    );
}

unsafe extern "C" fn parameter_callback(
    user: *const c_void,
    device: Handle,
    source: Handle,
    source_type: i32,
    severity: i32,
    code: i32,
    message: *const c_char,
) {
    record(
        2,
        user,
        device,
        source,
        (source_type, severity, code),
        message,
    );
}

/// Completion calls received: (user data, device, frame).
static COMPLETIONS: Mutex<Vec<(usize, usize, usize)>> = Mutex::new(Vec::new());

unsafe extern "C" fn on_frame_completion(user: *const c_void, device: Handle, frame: Handle) {
    COMPLETIONS
        .lock()
        .unwrap()
        .push((user as usize, device as usize, frame as usize));
}

// ----- locating and loading the libraries -----------------------------------------------------

/// The target directory and profile directory this test binary was built into.
fn build_dirs() -> (PathBuf, PathBuf) {
    let exe = std::env::current_exe().unwrap();
    let profile_dir = exe.parent().unwrap().parent().unwrap().to_path_buf();
    let target_dir = profile_dir.parent().unwrap().to_path_buf();
    (target_dir, profile_dir)
}

/// Builds the workspace member that produces libanari_library_cavetrace.so (a no-op when it is
/// up to date) and returns its path. `cargo test` alone does not build another package's cdylib.
/// The build uses this test run's profile, or `CAVETRACE_SDK_TEST_PROFILE` when set: the test
/// script asks for `release`, the build its C harness makes next anyway. (A `dev` build here
/// cannot reuse the tests' own build of cavetrace: the dev-dependencies turn on other features of
/// shared crates, so it would compile cavetrace a second time.)
fn sdk_library_path() -> PathBuf {
    static BUILT: OnceLock<PathBuf> = OnceLock::new();
    BUILT
        .get_or_init(|| {
            let (target_dir, test_profile_dir) = build_dirs();
            let test_profile = test_profile_dir.file_name().unwrap().to_str().unwrap();
            let profile = std::env::var("CAVETRACE_SDK_TEST_PROFILE")
                .unwrap_or_else(|_| test_profile.to_owned());
            // Cargo's `dev` profile writes to `debug`; every other profile to its own name.
            let (profile, output_dir) = match profile.as_str() {
                "dev" | "debug" => ("dev", "debug"),
                other => (other, other),
            };
            let profile_dir = target_dir.join(output_dir);
            let status = std::process::Command::new(env!("CARGO"))
                .args([
                    "build",
                    "--quiet",
                    "-p",
                    "anari_library_cavetrace",
                    "--profile",
                ])
                .arg(profile)
                .arg("--target-dir")
                .arg(&target_dir)
                .current_dir(env!("CARGO_MANIFEST_DIR"))
                .status()
                .expect("running cargo build for the SDK library");
            assert!(
                status.success(),
                "cargo build -p anari_library_cavetrace failed"
            );
            let path = profile_dir.join("libanari_library_cavetrace.so");
            assert!(path.exists(), "{} was not built", path.display());
            path
        })
        .clone()
}

/// libcavetrace.so as built for this test run.
fn cavetrace_library_path() -> PathBuf {
    let (_, profile_dir) = build_dirs();
    [profile_dir.join("deps"), profile_dir]
        .iter()
        .map(|d| d.join("libcavetrace.so"))
        .find(|p| p.exists())
        .expect("libcavetrace.so next to the test binary")
}

/// A private copy of `source` named `name`, so the dynamic loader treats it as a separate library.
fn copy_as(source: &Path, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cavetrace-sdk-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::copy(source, &path).unwrap();
    path
}

/// Deletes a copy once it is loaded (the loaded mapping stays valid).
fn remove_copy(path: &Path) {
    let _ = std::fs::remove_file(path);
    let _ = std::fs::remove_dir(path.parent().unwrap());
}

/// Puts a copy of libcavetrace.so into the global symbol scope, as the front end's `anari*`
/// functions are in a real application. It stays loaded for the whole process.
fn load_decoy() {
    static DECOY: OnceLock<usize> = OnceLock::new();
    DECOY.get_or_init(|| {
        let path = copy_as(&cavetrace_library_path(), "libdecoy_anari.so");
        // SAFETY: loading cavetrace runs no initialisers with preconditions.
        let decoy = unsafe { Library::open(Some(&path), RTLD_NOW | RTLD_GLOBAL) }.unwrap();
        remove_copy(&path);
        decoy.into_raw() as usize
    });
}

// ----- the scenario -----------------------------------------------------------------------------

/// An SDK device object driven through its vtable.
struct SdkDevice(Handle);

impl SdkDevice {
    fn new_with_subtype(&self, slot: usize, subtype: &str) -> Handle {
        let subtype = c(subtype);
        virtual_call!(self.0, slot, (*const c_char) -> Handle; subtype.as_ptr())
    }
    fn new_plain(&self, slot: usize) -> Handle {
        virtual_call!(self.0, slot, () -> Handle;)
    }
    fn set<T>(&self, object: Handle, name: &str, data_type: i32, value: &T) {
        let name = c(name);
        virtual_call!(
            self.0,
            device_slot::SET_PARAMETER,
            (Handle, *const c_char, i32, *const c_void);
            object, name.as_ptr(), data_type, value as *const T as *const c_void
        )
    }
    /// An ANARI_VOID_POINTER parameter: its value is passed as `mem` itself, not by address.
    fn set_void_pointer(&self, object: Handle, name: &str, value: usize) {
        let name = c(name);
        virtual_call!(
            self.0,
            device_slot::SET_PARAMETER,
            (Handle, *const c_char, i32, *const c_void);
            object, name.as_ptr(), ANARI_VOID_POINTER, value as *const c_void
        )
    }
    fn set_string(&self, object: Handle, name: &str, value: &str) {
        let (name, value) = (c(name), c(value));
        virtual_call!(
            self.0,
            device_slot::SET_PARAMETER,
            (Handle, *const c_char, i32, *const c_void);
            object, name.as_ptr(), ANARI_STRING, value.as_ptr() as *const c_void
        )
    }
    fn unset(&self, object: Handle, name: &str) {
        let name = c(name);
        virtual_call!(
            self.0, device_slot::UNSET_PARAMETER, (Handle, *const c_char); object, name.as_ptr()
        )
    }
    fn unset_all(&self, object: Handle) {
        virtual_call!(self.0, device_slot::UNSET_ALL_PARAMETERS, (Handle); object)
    }
    fn commit(&self, object: Handle) {
        virtual_call!(self.0, device_slot::COMMIT_PARAMETERS, (Handle); object)
    }
    fn release(&self, object: Handle) {
        virtual_call!(self.0, device_slot::RELEASE, (Handle); object)
    }
    fn retain(&self, object: Handle) {
        virtual_call!(self.0, device_slot::RETAIN, (Handle); object)
    }
    fn get_property<T: Default>(&self, object: Handle, name: &str, data_type: i32) -> Option<T> {
        let name = c(name);
        let mut value = T::default();
        let found = virtual_call!(
            self.0,
            device_slot::GET_PROPERTY,
            (Handle, *const c_char, i32, *mut c_void, u64, u32) -> c_int;
            object, name.as_ptr(), data_type, &mut value as *mut T as *mut c_void,
            std::mem::size_of::<T>() as u64, ANARI_WAIT
        );
        (found == 1).then_some(value)
    }
    fn render_and_wait(&self, frame: Handle) {
        virtual_call!(self.0, device_slot::RENDER_FRAME, (Handle); frame);
        let ready = virtual_call!(self.0, device_slot::FRAME_READY, (Handle, u32) -> c_int; frame, ANARI_WAIT);
        assert_eq!(ready, 1);
    }
    /// Maps a FLOAT32_VEC4 colour channel and copies it out (rows bottom to top).
    fn read_color(&self, frame: Handle) -> (Vec<[f32; 4]>, u32, u32) {
        let channel = c("channel.color");
        let (mut width, mut height, mut pixel_type) = (0u32, 0u32, 0i32);
        let pixels = virtual_call!(
            self.0,
            device_slot::FRAME_BUFFER_MAP,
            (Handle, *const c_char, *mut u32, *mut u32, *mut i32) -> *const c_void;
            frame, channel.as_ptr(), &mut width, &mut height, &mut pixel_type
        );
        assert!(!pixels.is_null(), "channel.color did not map");
        assert_eq!(pixel_type, ANARI_FLOAT32_VEC4);
        // SAFETY: the mapped channel holds width × height FLOAT32_VEC4 pixels until unmapped.
        let copy = unsafe {
            std::slice::from_raw_parts(pixels as *const [f32; 4], (width * height) as usize)
        }
        .to_vec();
        virtual_call!(
            self.0, device_slot::FRAME_BUFFER_UNMAP, (Handle, *const c_char); frame, channel.as_ptr()
        );
        (copy, width, height)
    }
}

/// One `ANARIParameterValue` of anariNewInitializedDevice's list.
#[repr(C)]
struct ParameterValue {
    name: *const c_char,
    data_type: i32,
    value: *const c_void,
}

/// `binds_own_symbols`: the library resolves its own exported names itself (as the SDK library,
/// linked with -Bsymbolic, does), so anariDeviceGetProcAddress answers with its own functions
/// even when another copy sits in the global scope. A `temporary` library file is deleted once
/// loaded.
fn run_scenario(library_path: &Path, binds_own_symbols: bool, temporary: bool) {
    load_decoy();
    let log = Box::new(Log::default());
    let log_pointer = &*log as *const Log as *const c_void;

    // SAFETY: loading cavetrace runs no initialisers with preconditions.
    let dl = unsafe { Library::open(Some(library_path), RTLD_LAZY | RTLD_LOCAL) }.unwrap();
    if temporary {
        remove_copy(library_path);
    }
    // SAFETY: the symbol has the SDK entry point's signature.
    let entry = unsafe {
        dl.get::<unsafe extern "C" fn(*mut c_void, StatusCallback, *const c_void) -> Handle>(
            b"anari_library_cavetrace_new_library\0",
        )
    }
    .unwrap();
    let entry = *entry;
    // cavetrace's own device counter, looked up in this library (not in the global scope).
    // SAFETY: cavetraceLiveDeviceCount has this signature.
    let live_devices =
        *unsafe { dl.get::<extern "C" fn() -> u64>(b"cavetraceLiveDeviceCount\0") }.unwrap();
    let dl_handle = dl.into_raw();

    // The library object: {vtable, dlHandle, defaultCallback, defaultUserPtr}.
    // SAFETY: the entry point's documented contract.
    let library = unsafe { entry(dl_handle, default_callback, log_pointer) };
    assert!(!library.is_null());
    assert_eq!(
        word_at(library, 8),
        dl_handle as usize,
        "dlHandle at byte 8"
    );
    assert_eq!(
        word_at(library, 16),
        default_callback as StatusCallback as usize
    );
    assert_eq!(word_at(library, 24), log_pointer as usize);

    let subtypes = string_list(virtual_call!(
        library, library_slot::GET_DEVICE_SUBTYPES, () -> *const *const c_char;
    ));
    assert_eq!(subtypes[0], "default");
    let default = c("default");
    let extensions = string_list(virtual_call!(
        library, library_slot::GET_DEVICE_EXTENSIONS, (*const c_char) -> *const *const c_char;
        default.as_ptr()
    ));
    assert!(
        extensions
            .iter()
            .any(|e| e.ends_with("ANARI_KHR_GEOMETRY_TRIANGLE")),
        "{extensions:?}"
    );

    // Unknown device subtype: NULL, and an error from the library to the default callback.
    let bogus = c("no-such-device");
    let none =
        virtual_call!(library, library_slot::NEW_DEVICE, (*const c_char) -> Handle; bogus.as_ptr());
    assert!(none.is_null());
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!(
        (
            errors[0].callback,
            errors[0].device,
            errors[0].source,
            errors[0].source_type
        ),
        (1, 0, library as usize, ANARI_LIBRARY)
    );
    let module = c("helide");
    virtual_call!(library, library_slot::LOAD_MODULE, (*const c_char); module.as_ptr());
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!(errors[0].code, ANARI_STATUS_INVALID_OPERATION);

    // The device object begins {vtable, defaultStatusCB, defaultStatusCBUserPtr}.
    let dev = SdkDevice(virtual_call!(
        library, library_slot::NEW_DEVICE, (*const c_char) -> Handle; default.as_ptr()
    ));
    assert!(!dev.0.is_null());
    assert_eq!(
        word_at(dev.0, 8),
        default_callback as StatusCallback as usize
    );
    assert_eq!(word_at(dev.0, 16), log_pointer as usize);

    // cavetrace's extension functions by name (slot 38).
    let name = c("cavetraceLiveDeviceCount");
    let live_count_address = virtual_call!(
        dev.0, device_slot::GET_PROC_ADDRESS, (*const c_char) -> usize; name.as_ptr()
    );
    assert_ne!(live_count_address, 0);
    if binds_own_symbols {
        assert_eq!(live_count_address, live_devices as usize);
    }
    let live_before = live_devices();

    // Messages carry the SDK device pointer, both as device and as source for the device itself.
    dev.set(dev.0, "noSuchDeviceParameter", ANARI_INT32, &1i32);
    let warnings = log.take();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert_eq!(warnings[0].severity, ANARI_SEVERITY_WARNING);
    assert_eq!(
        (
            warnings[0].device,
            warnings[0].source,
            warnings[0].source_type
        ),
        (dev.0 as usize, dev.0 as usize, ANARI_DEVICE)
    );

    // A triangle at z = −3 in front of a camera at the origin looking down −z.
    let geometry = dev.new_with_subtype(device_slot::NEW_GEOMETRY, "triangle");
    let positions = [[-1.0f32, -1.0, -3.0], [1.0, -1.0, -3.0], [0.0, 1.0, -3.0]];
    let position_array = virtual_call!(
        dev.0,
        device_slot::NEW_ARRAY_1D,
        (*const c_void, usize, *const c_void, i32, u64) -> Handle;
        std::ptr::null(), 0, std::ptr::null(), ANARI_FLOAT32_VEC3, 3
    );
    let mapped =
        virtual_call!(dev.0, device_slot::MAP_ARRAY, (Handle) -> *mut c_void; position_array);
    assert!(!mapped.is_null());
    // SAFETY: a managed array of three FLOAT32_VEC3, mapped for writing.
    unsafe { std::ptr::copy_nonoverlapping(positions.as_ptr(), mapped as *mut [f32; 3], 3) };
    virtual_call!(dev.0, device_slot::UNMAP_ARRAY, (Handle); position_array);
    dev.set(geometry, "vertex.position", ANARI_ARRAY1D, &position_array);
    dev.commit(geometry);

    // Errors about an object name that object and the SDK device.
    dev.set(geometry, "vertex.position", ANARI_FLOAT32, &1.0f32);
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!(
        (errors[0].device, errors[0].source, errors[0].code),
        (
            dev.0 as usize,
            geometry as usize,
            ANARI_STATUS_INVALID_ARGUMENT
        )
    );

    let material = dev.new_with_subtype(device_slot::NEW_MATERIAL, "matte");
    dev.set(material, "color", ANARI_FLOAT32_VEC3, &[1.0f32, 0.0, 0.0]);
    dev.commit(material);
    let surface = dev.new_plain(device_slot::NEW_SURFACE);
    dev.set(surface, "geometry", ANARI_GEOMETRY, &geometry);
    dev.set(surface, "material", ANARI_MATERIAL, &material);
    dev.commit(surface);

    // The world's surface list through anariMapParameterArray1D (slots 19 and 22).
    let world = dev.new_plain(device_slot::NEW_WORLD);
    let surface_name = c("surface");
    let mut stride = 0u64;
    let surfaces = virtual_call!(
        dev.0,
        device_slot::MAP_PARAMETER_ARRAY_1D,
        (Handle, *const c_char, i32, u64, *mut u64) -> *mut c_void;
        world, surface_name.as_ptr(), ANARI_SURFACE, 1, &mut stride
    );
    assert!(!surfaces.is_null());
    assert_eq!(stride, 8);
    // SAFETY: a mapped array of one ANARI_SURFACE handle.
    unsafe { (surfaces as *mut Handle).write(surface) };
    virtual_call!(
        dev.0, device_slot::UNMAP_PARAMETER_ARRAY, (Handle, *const c_char); world, surface_name.as_ptr()
    );
    dev.commit(world);
    let bounds: Option<[f32; 6]> = dev.get_property(world, "bounds", ANARI_FLOAT32_BOX3);
    assert_eq!(bounds, Some([-1.0, -1.0, -3.0, 1.0, 1.0, -3.0]));

    let camera = dev.new_with_subtype(device_slot::NEW_CAMERA, "perspective");
    dev.set(camera, "position", ANARI_FLOAT32_VEC3, &[0.0f32, 0.0, 0.0]);
    dev.set(
        camera,
        "direction",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, 0.0, -1.0],
    );
    dev.set(camera, "up", ANARI_FLOAT32_VEC3, &[0.0f32, 1.0, 0.0]);
    dev.set(camera, "aspect", ANARI_FLOAT32, &1.0f32);
    dev.commit(camera);
    let renderer = dev.new_with_subtype(device_slot::NEW_RENDERER, "default");
    let background = [0.0f32, 0.0, 1.0, 1.0];
    dev.set(renderer, "background", ANARI_FLOAT32_VEC4, &background);
    dev.set(renderer, "ambientRadiance", ANARI_FLOAT32, &1.0f32);
    dev.commit(renderer);

    let frame = dev.new_plain(device_slot::NEW_FRAME);
    dev.set(frame, "size", ANARI_UINT32_VEC2, &[32u32, 32]);
    dev.set(frame, "channel.color", ANARI_DATA_TYPE, &ANARI_FLOAT32_VEC4);
    dev.set(frame, "world", ANARI_WORLD, &world);
    dev.set(frame, "camera", ANARI_CAMERA, &camera);
    dev.set(frame, "renderer", ANARI_RENDERER, &renderer);
    let completion_user = 0x5eedusize;
    dev.set(
        frame,
        "frameCompletionCallback",
        ANARI_FRAME_COMPLETION_CALLBACK,
        &(on_frame_completion as CompletionCallback),
    );
    // NULL is a valid user pointer, not a missing value.
    dev.set_void_pointer(frame, "frameCompletionCallbackUserData", 0);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
    // Not a readable address: a device that dereferenced the user pointer would crash here.
    dev.set_void_pointer(frame, "frameCompletionCallbackUserData", completion_user);
    dev.commit(frame);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");

    dev.render_and_wait(frame);
    let (color, width, height) = dev.read_color(frame);
    assert_eq!((width, height), (32, 32));
    let centre = color[16 * 32 + 16];
    // Red matte lit by the ambient light only: red, no green or blue (ambient radiance × albedo).
    assert!(
        centre[0] > 0.1 && centre[1] == 0.0 && centre[2] == 0.0,
        "centre {centre:?}"
    );
    assert_eq!(color[0], background, "corner");
    // The render thread calls back right after it marks the frame ready, so allow it a moment.
    let completions = || -> Vec<(usize, usize, usize)> {
        let all = COMPLETIONS.lock().unwrap();
        all.iter()
            .copied()
            .filter(|c| c.1 == dev.0 as usize)
            .collect()
    };
    for _ in 0..1000 {
        if !completions().is_empty() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    assert_eq!(
        completions(),
        [(completion_user, dev.0 as usize, frame as usize)]
    );
    let duration: Option<f32> = dev.get_property(frame, "duration", ANARI_FLOAT32);
    assert!(duration.is_some_and(|d| d >= 0.0), "{duration:?}");
    virtual_call!(dev.0, device_slot::DISCARD_FRAME, (Handle); frame);

    // The device's statusCallback parameter takes effect at the device's commit.
    let parameter_callback_fn: StatusCallback = parameter_callback;
    dev.set(
        dev.0,
        "statusCallback",
        ANARI_STATUS_CALLBACK,
        &parameter_callback_fn,
    );
    dev.set_void_pointer(dev.0, "statusCallbackUserData", log_pointer as usize);
    dev.set(geometry, "vertex.position", ANARI_FLOAT32, &1.0f32);
    assert_eq!(
        log.errors().iter().map(|m| m.callback).collect::<Vec<_>>(),
        [1]
    );
    dev.commit(dev.0);
    dev.set(geometry, "vertex.position", ANARI_FLOAT32, &1.0f32);
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!((errors[0].callback, errors[0].device), (2, dev.0 as usize));
    // Unsetting it (slot 17) brings the library's default callback back at the next commit.
    dev.unset(dev.0, "statusCallback");
    dev.commit(dev.0);
    dev.set(geometry, "vertex.position", ANARI_FLOAT32, &1.0f32);
    assert_eq!(
        log.errors().iter().map(|m| m.callback).collect::<Vec<_>>(),
        [1]
    );

    // Device properties through the device handle itself.
    let version: Option<i32> = dev.get_property(dev.0, "version", ANARI_INT32);
    assert!(version.is_some());

    // Introspection (slots 29–31).
    let geometries = string_list(virtual_call!(
        dev.0, device_slot::GET_OBJECT_SUBTYPES, (i32) -> *const *const c_char; ANARI_GEOMETRY
    ));
    assert!(geometries.iter().any(|g| g == "triangle"), "{geometries:?}");
    let (triangle, parameter) = (c("triangle"), c("parameter"));
    let parameters = virtual_call!(
        dev.0,
        device_slot::GET_OBJECT_INFO,
        (i32, *const c_char, *const c_char, i32) -> *const c_void;
        ANARI_GEOMETRY, triangle.as_ptr(), parameter.as_ptr(), ANARI_PARAMETER_LIST
    );
    assert!(!parameters.is_null());
    let (vertex_position, required) = (c("vertex.position"), c("required"));
    let is_required = virtual_call!(
        dev.0,
        device_slot::GET_PARAMETER_INFO,
        (i32, *const c_char, *const c_char, i32, *const c_char, i32) -> *const c_void;
        ANARI_GEOMETRY, triangle.as_ptr(), vertex_position.as_ptr(), ANARI_ARRAY1D,
        required.as_ptr(), ANARI_BOOL
    );
    assert!(!is_required.is_null());
    // SAFETY: an ANARI_BOOL answer is one byte.
    assert_eq!(unsafe { *(is_required as *const u8) }, 1);
    let extension = c("extension");
    let triangle_extensions = virtual_call!(
        dev.0,
        device_slot::GET_OBJECT_INFO,
        (i32, *const c_char, *const c_char, i32) -> *const *const c_char;
        ANARI_GEOMETRY, triangle.as_ptr(), extension.as_ptr(), ANARI_STRING_LIST
    );
    assert!(
        string_list(triangle_extensions)
            .iter()
            .any(|e| e.ends_with("ANARI_KHR_GEOMETRY_TRIANGLE"))
    );

    // 2D and 3D arrays (slots 1 and 2): the kinds are checked where they are used.
    let texels = [[1.0f32, 1.0, 1.0, 1.0]; 4];
    let image = virtual_call!(
        dev.0,
        device_slot::NEW_ARRAY_2D,
        (*const c_void, usize, *const c_void, i32, u64, u64) -> Handle;
        texels.as_ptr() as *const c_void, 0, std::ptr::null(), ANARI_FLOAT32_VEC4, 2, 2
    );
    let sampler = dev.new_with_subtype(device_slot::NEW_SAMPLER, "image2D");
    dev.set(sampler, "image", ANARI_ARRAY2D, &image);
    let voxels = [0.0f32; 8];
    let volume_data = virtual_call!(
        dev.0,
        device_slot::NEW_ARRAY_3D,
        (*const c_void, usize, *const c_void, i32, u64, u64, u64) -> Handle;
        voxels.as_ptr() as *const c_void, 0, std::ptr::null(), ANARI_FLOAT32, 2, 2, 2
    );
    dev.set(sampler, "probe3D", ANARI_ARRAY3D, &volume_data);
    dev.set(sampler, "probe2D", ANARI_ARRAY2D, &volume_data);
    let errors = log.errors();
    assert_eq!(
        errors.len(),
        1,
        "only the 3D array given as 2D is refused: {errors:?}"
    );
    assert!(errors[0].text.contains("probe2D"), "{errors:?}");

    // anariNewObject (slot 37).
    let (geometry_kind, sphere) = (c("geometry"), c("sphere"));
    let generic = virtual_call!(
        dev.0, device_slot::NEW_OBJECT, (*const c_char, *const c_char) -> Handle;
        geometry_kind.as_ptr(), sphere.as_ptr()
    );
    assert!(!generic.is_null());

    // Unsetting all of a frame's parameters (slot 18) leaves it without a size.
    dev.unset_all(frame);
    dev.commit(frame);
    virtual_call!(dev.0, device_slot::RENDER_FRAME, (Handle); frame);
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!(
        (errors[0].source, errors[0].source_type),
        (frame as usize, ANARI_FRAME)
    );

    // Objects: released by handle; the label name is a string parameter every object takes.
    dev.set_string(geometry, "name", "the triangle");
    for object in [
        position_array,
        geometry,
        material,
        surface,
        world,
        camera,
        renderer,
        frame,
        image,
        sampler,
        volume_data,
        generic,
    ] {
        dev.release(object);
    }
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");

    // Retained once more, the device survives one release (slots 25 and 24 on itself).
    dev.retain(dev.0);
    dev.release(dev.0);
    assert_eq!(live_devices(), live_before);
    let version_again: Option<i32> = dev.get_property(dev.0, "version", ANARI_INT32);
    assert_eq!(version_again, version);
    dev.release(dev.0);
    assert_eq!(
        live_devices(),
        live_before - 1,
        "the last release ends the device"
    );

    // A second device, with initial parameters (slot 3), destroyed by C++ delete (slot 40).
    let initial_threads = 2u32;
    let threads_name = c("numThreads");
    let initializers = [
        ParameterValue {
            name: threads_name.as_ptr(),
            data_type: ANARI_UINT32,
            value: &initial_threads as *const u32 as *const c_void,
        },
        ParameterValue {
            name: std::ptr::null(),
            data_type: 0,
            value: std::ptr::null(),
        },
    ];
    let second = virtual_call!(
        library,
        library_slot::NEW_INITIALIZED_DEVICE,
        (*const c_char, *const ParameterValue) -> Handle;
        default.as_ptr(), initializers.as_ptr()
    );
    assert!(!second.is_null());
    assert_eq!(live_devices(), live_before);
    let second = SdkDevice(second);
    second.retain(second.0);
    virtual_call!(second.0, device_slot::DELETING_DESTRUCTOR, (););
    assert_eq!(
        live_devices(),
        live_before - 1,
        "delete ends the device despite a retain"
    );

    // The library: deleted through slot 1, then dlclosed by handle, as the front end does.
    virtual_call!(library, library_slot::DELETING_DESTRUCTOR, (););
    let messages = log.take();
    assert!(messages.is_empty(), "{messages:?}");
    // SAFETY: the handle came from into_raw; nothing of the library is used after this.
    drop(unsafe { Library::from_raw(dl_handle) });
}

#[test]
fn the_sdk_library_renders_through_the_sdk_device_interface() {
    run_scenario(&sdk_library_path(), true, false);
}

/// libcavetrace.so exports the same entry point. Loaded as the SDK would load it, without the
/// SDK library's -Bsymbolic, every `anari*` call it made to itself would reach the decoy: the
/// scenario passing shows `cavetrace::sdk` makes none.
#[test]
fn libcavetrace_itself_serves_the_sdk_without_calling_its_exported_functions() {
    let copy = copy_as(&cavetrace_library_path(), "libanari_library_cavetrace.so");
    run_scenario(&copy, false, true);
}
