//! The shared library as a C application loads it at run time: libcavetrace.so opened with
//! libloading, every exported function resolved by name, and a device driven through the C ABI
//! to render a triangle whose pixels are checked.

use std::ffi::{CStr, c_char, c_int, c_void};
use std::path::PathBuf;
use std::sync::Mutex;

use libloading::{Library, Symbol};

/// Every function the library exports: the ANARI 1.0 API and cavetrace's own.
const EXPORTED: &[&str] = &[
    "anariLoadLibrary",
    "anariUnloadLibrary",
    "anariLoadModule",
    "anariUnloadModule",
    "anariNewDevice",
    "anariNewInitializedDevice",
    "anariNewArray1D",
    "anariNewArray2D",
    "anariNewArray3D",
    "anariMapArray",
    "anariUnmapArray",
    "anariNewLight",
    "anariNewCamera",
    "anariNewGeometry",
    "anariNewSpatialField",
    "anariNewVolume",
    "anariNewSurface",
    "anariNewMaterial",
    "anariNewSampler",
    "anariNewGroup",
    "anariNewInstance",
    "anariNewWorld",
    "anariNewObject",
    "anariSetParameter",
    "anariUnsetParameter",
    "anariUnsetAllParameters",
    "anariMapParameterArray1D",
    "anariMapParameterArray2D",
    "anariMapParameterArray3D",
    "anariUnmapParameterArray",
    "anariCommitParameters",
    "anariRelease",
    "anariRetain",
    "anariGetDeviceSubtypes",
    "anariGetDeviceExtensions",
    "anariGetObjectSubtypes",
    "anariGetObjectInfo",
    "anariGetParameterInfo",
    "anariGetProperty",
    "anariNewFrame",
    "anariMapFrame",
    "anariUnmapFrame",
    "anariNewRenderer",
    "anariRenderFrame",
    "anariFrameReady",
    "anariDiscardFrame",
    "anariDeviceGetProcAddress",
    "cavetraceLiveDeviceCount",
    "cavetraceWriteFramePNG",
    "cavetraceWriteImagePNG",
    "cavetraceOffAxisMatrices",
    "cavetraceOffAxisPerspective",
    "cavetracePerspectiveFromMatrices",
];

const ANARI_FLOAT32: c_int = 1068;
const ANARI_FLOAT32_VEC3: c_int = 1070;
const ANARI_FLOAT32_VEC4: c_int = 1071;
const ANARI_UINT32: c_int = 1020;
const ANARI_UINT32_VEC2: c_int = 1021;
const ANARI_DATA_TYPE: c_int = 100;
const ANARI_ARRAY1D: c_int = 504;
const ANARI_SURFACE: c_int = 515;
const ANARI_GEOMETRY: c_int = 509;
const ANARI_MATERIAL: c_int = 513;
const ANARI_WORLD: c_int = 519;
const ANARI_CAMERA: c_int = 507;
const ANARI_RENDERER: c_int = 514;
const ANARI_WAIT: u32 = 1;
const ANARI_SEVERITY_ERROR: c_int = 2;

type Handle = *mut c_void;
type StatusCallback =
    unsafe extern "C" fn(*const c_void, Handle, Handle, c_int, c_int, c_int, *const c_char);

/// The libcavetrace.so cargo built for this test run: beside the test executable in
/// target/<profile>/deps, where cargo writes the cdylib when it builds the crate for integration
/// tests; target/<profile>/libcavetrace.so (copied there by `cargo build`) otherwise.
fn library_path() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let deps = exe.parent().expect("target/<profile>/deps");
    let beside = deps.join("libcavetrace.so");
    if beside.exists() {
        return beside;
    }
    deps.parent()
        .expect("target/<profile>")
        .join("libcavetrace.so")
}

/// Errors received through the status callback.
static ERRORS: Mutex<Vec<String>> = Mutex::new(Vec::new());

unsafe extern "C" fn record_errors(
    _user: *const c_void,
    _device: Handle,
    _source: Handle,
    _source_type: c_int,
    severity: c_int,
    _code: c_int,
    message: *const c_char,
) {
    if severity <= ANARI_SEVERITY_ERROR {
        // SAFETY: the device passes a NUL-terminated message valid during the call.
        let text = unsafe { CStr::from_ptr(message) }
            .to_string_lossy()
            .into_owned();
        ERRORS.lock().unwrap().push(text);
    }
}

/// The C functions the test drives, resolved from the loaded library.
struct Api<'lib> {
    load_library:
        Symbol<'lib, unsafe extern "C" fn(*const c_char, StatusCallback, *const c_void) -> Handle>,
    unload_library: Symbol<'lib, unsafe extern "C" fn(Handle)>,
    new_device: Symbol<'lib, unsafe extern "C" fn(Handle, *const c_char) -> Handle>,
    new_array1d: Symbol<
        'lib,
        unsafe extern "C" fn(
            Handle,
            *const c_void,
            *const c_void,
            *const c_void,
            c_int,
            u64,
        ) -> Handle,
    >,
    map_array: Symbol<'lib, unsafe extern "C" fn(Handle, Handle) -> *mut c_void>,
    unmap_array: Symbol<'lib, unsafe extern "C" fn(Handle, Handle)>,
    new_with_subtype: [Symbol<'lib, unsafe extern "C" fn(Handle, *const c_char) -> Handle>; 4],
    new_without_subtype: [Symbol<'lib, unsafe extern "C" fn(Handle) -> Handle>; 3],
    set_parameter:
        Symbol<'lib, unsafe extern "C" fn(Handle, Handle, *const c_char, c_int, *const c_void)>,
    commit: Symbol<'lib, unsafe extern "C" fn(Handle, Handle)>,
    release: Symbol<'lib, unsafe extern "C" fn(Handle, Handle)>,
    render: Symbol<'lib, unsafe extern "C" fn(Handle, Handle)>,
    frame_ready: Symbol<'lib, unsafe extern "C" fn(Handle, Handle, u32) -> c_int>,
    map_frame: Symbol<
        'lib,
        unsafe extern "C" fn(
            Handle,
            Handle,
            *const c_char,
            *mut u32,
            *mut u32,
            *mut c_int,
        ) -> *const c_void,
    >,
    unmap_frame: Symbol<'lib, unsafe extern "C" fn(Handle, Handle, *const c_char)>,
    live_devices: Symbol<'lib, unsafe extern "C" fn() -> u64>,
}

/// Resolves a symbol of type T by its C name.
fn symbol<'lib, T>(library: &'lib Library, name: &str) -> Symbol<'lib, T> {
    let mut bytes = name.as_bytes().to_vec();
    bytes.push(0);
    // SAFETY: each call site names T as the C signature the header declares for `name`.
    unsafe { library.get::<T>(&bytes) }.unwrap_or_else(|e| panic!("{name}: {e}"))
}

impl<'lib> Api<'lib> {
    fn resolve(library: &'lib Library) -> Api<'lib> {
        Api {
            load_library: symbol(library, "anariLoadLibrary"),
            unload_library: symbol(library, "anariUnloadLibrary"),
            new_device: symbol(library, "anariNewDevice"),
            new_array1d: symbol(library, "anariNewArray1D"),
            map_array: symbol(library, "anariMapArray"),
            unmap_array: symbol(library, "anariUnmapArray"),
            new_with_subtype: [
                symbol(library, "anariNewGeometry"),
                symbol(library, "anariNewMaterial"),
                symbol(library, "anariNewCamera"),
                symbol(library, "anariNewRenderer"),
            ],
            new_without_subtype: [
                symbol(library, "anariNewSurface"),
                symbol(library, "anariNewWorld"),
                symbol(library, "anariNewFrame"),
            ],
            set_parameter: symbol(library, "anariSetParameter"),
            commit: symbol(library, "anariCommitParameters"),
            release: symbol(library, "anariRelease"),
            render: symbol(library, "anariRenderFrame"),
            frame_ready: symbol(library, "anariFrameReady"),
            map_frame: symbol(library, "anariMapFrame"),
            unmap_frame: symbol(library, "anariUnmapFrame"),
            live_devices: symbol(library, "cavetraceLiveDeviceCount"),
        }
    }
}

fn open() -> Library {
    let path = library_path();
    assert!(path.exists(), "{} was not built", path.display());
    // SAFETY: loading cavetrace runs no initialisation code with preconditions.
    unsafe { Library::new(&path) }.unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn every_exported_function_resolves_by_name() {
    let library = open();
    let missing: Vec<&str> = EXPORTED
        .iter()
        .copied()
        .filter(|name| {
            let bytes = format!("{name}\0");
            // SAFETY: only the presence of the symbol is checked; it is never called.
            unsafe { library.get::<unsafe extern "C" fn()>(bytes.as_bytes()) }.is_err()
        })
        .collect();
    assert!(missing.is_empty(), "not exported: {missing:?}");
}

#[test]
fn a_triangle_renders_through_the_c_abi() {
    let library = open();
    let api = Api::resolve(&library);
    let c = |s: &str| std::ffi::CString::new(s).unwrap();
    // SAFETY: every call passes arguments of the C types the header declares, pointers to live
    // values of the declared ANARI types, and handles created by this device.
    unsafe {
        let lib = (api.load_library)(c("cavetrace").as_ptr(), record_errors, std::ptr::null());
        assert!(!lib.is_null());
        let dev = (api.new_device)(lib, c("default").as_ptr());
        assert!(!dev.is_null());
        assert!((api.live_devices)() >= 1);
        let set = |object: Handle, name: &str, data_type: c_int, value: *const c_void| {
            (api.set_parameter)(dev, object, c(name).as_ptr(), data_type, value)
        };
        let [new_geometry, new_material, new_camera, new_renderer] = &api.new_with_subtype;
        let [new_surface, new_world, new_frame] = &api.new_without_subtype;

        let positions: [[f32; 3]; 3] = [[-1.0, -1.0, -3.0], [1.0, -1.0, -3.0], [0.0, 1.0, -3.0]];
        let array = (api.new_array1d)(
            dev,
            std::ptr::null(),
            std::ptr::null(),
            std::ptr::null(),
            ANARI_FLOAT32_VEC3,
            3,
        );
        let memory = (api.map_array)(dev, array) as *mut [f32; 3];
        assert!(!memory.is_null());
        std::ptr::copy_nonoverlapping(positions.as_ptr(), memory, 3);
        (api.unmap_array)(dev, array);
        let geometry = new_geometry(dev, c("triangle").as_ptr());
        set(
            geometry,
            "vertex.position",
            ANARI_ARRAY1D,
            &array as *const Handle as _,
        );
        (api.commit)(dev, geometry);

        let material = new_material(dev, c("matte").as_ptr());
        let green = [0.0f32, 1.0, 0.0];
        set(material, "color", ANARI_FLOAT32_VEC3, green.as_ptr() as _);
        (api.commit)(dev, material);
        let surface = new_surface(dev);
        set(
            surface,
            "geometry",
            ANARI_GEOMETRY,
            &geometry as *const Handle as _,
        );
        set(
            surface,
            "material",
            ANARI_MATERIAL,
            &material as *const Handle as _,
        );
        let id = 77u32;
        set(surface, "id", ANARI_UINT32, &id as *const u32 as _);
        (api.commit)(dev, surface);
        let surfaces = (api.new_array1d)(
            dev,
            &surface as *const Handle as _,
            std::ptr::null(),
            std::ptr::null(),
            ANARI_SURFACE,
            1,
        );
        let world = new_world(dev);
        set(
            world,
            "surface",
            ANARI_ARRAY1D,
            &surfaces as *const Handle as _,
        );
        (api.commit)(dev, world);

        let camera = new_camera(dev, c("perspective").as_ptr());
        (api.commit)(dev, camera);
        let renderer = new_renderer(dev, c("default").as_ptr());
        // Ambient radiance 1 from every direction: a matte surface shows exactly its albedo.
        let one = 1.0f32;
        set(
            renderer,
            "ambientRadiance",
            ANARI_FLOAT32,
            &one as *const f32 as _,
        );
        (api.commit)(dev, renderer);

        let frame = new_frame(dev);
        let size = [48u32, 32];
        set(frame, "size", ANARI_UINT32_VEC2, size.as_ptr() as _);
        for (channel, data_type) in [
            ("channel.color", ANARI_FLOAT32_VEC4),
            ("channel.depth", ANARI_FLOAT32),
            ("channel.objectId", ANARI_UINT32),
        ] {
            set(
                frame,
                channel,
                ANARI_DATA_TYPE,
                &data_type as *const c_int as _,
            );
        }
        set(frame, "world", ANARI_WORLD, &world as *const Handle as _);
        set(frame, "camera", ANARI_CAMERA, &camera as *const Handle as _);
        set(
            frame,
            "renderer",
            ANARI_RENDERER,
            &renderer as *const Handle as _,
        );
        (api.commit)(dev, frame);
        (api.render)(dev, frame);
        assert_eq!((api.frame_ready)(dev, frame, ANARI_WAIT), 1);

        let centre = 16 * 48 + 24;
        let (mut w, mut h, mut t) = (0u32, 0u32, 0);
        let color = c("channel.color");
        let pixels = (api.map_frame)(dev, frame, color.as_ptr(), &mut w, &mut h, &mut t);
        assert!(!pixels.is_null(), "{:?}", ERRORS.lock().unwrap());
        assert_eq!((w, h, t), (48, 32, ANARI_FLOAT32_VEC4));
        let rgba = std::slice::from_raw_parts(pixels as *const [f32; 4], (w * h) as usize);
        assert!((rgba[centre][1] - 1.0).abs() < 0.01, "{:?}", rgba[centre]);
        assert_eq!(rgba[centre][0], 0.0);
        assert_eq!(
            rgba[0],
            [0.0, 0.0, 0.0, 1.0],
            "the corner shows the background"
        );
        (api.unmap_frame)(dev, frame, color.as_ptr());

        let ids_name = c("channel.objectId");
        let ids = (api.map_frame)(
            dev,
            frame,
            ids_name.as_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
        ) as *const u32;
        assert_eq!(*ids.add(centre), 77);
        assert_eq!(*ids, u32::MAX);
        (api.unmap_frame)(dev, frame, ids_name.as_ptr());

        for object in [
            array, geometry, material, surface, surfaces, world, camera, renderer, frame,
        ] {
            (api.release)(dev, object);
        }
        (api.release)(dev, dev);
        (api.unload_library)(lib);
    }
    let errors = ERRORS.lock().unwrap().clone();
    assert!(errors.is_empty(), "{errors:?}");
}
