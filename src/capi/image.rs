//! cavetrace's PNG helpers: cavetraceWriteFramePNG (a frame channel) and cavetraceWriteImagePNG
//! (pixels the application composed itself, e.g. a stereo pair). Both read rows bottom to top,
//! as ANARI frames store them, and write an 8-bit RGBA PNG with the top row first.

use std::ffi::{c_char, c_void};
use std::fs::File;
use std::io::BufWriter;

use crate::capi::types::*;
use crate::capi::{device_of, guard, string_arg};
use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::status::*;
use crate::render::color::{encode_srgb8, to_unorm8};

/// Pixel types the helpers can write, as listed in messages.
const WRITABLE_TYPES: &[ANARIDataType] = &[
    ANARI_UFIXED8_RGBA_SRGB,
    ANARI_UFIXED8_RGB_SRGB,
    ANARI_UFIXED8_VEC4,
    ANARI_UFIXED8_VEC3,
    ANARI_FLOAT32_VEC4,
    ANARI_FLOAT32_VEC3,
    ANARI_FLOAT32,
    ANARI_UINT32,
];

/// How the values of a pixel type are turned into something visible.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Meaning {
    /// Linear or sRGB colour, by the pixel type.
    Color,
    /// Unit vectors in [-1,1]³ shown as (n + 1) / 2 (channel.normal).
    Normal,
    /// Distances: nearest white, farthest dark grey, non-finite (no hit) black.
    Distance,
    /// OpenGL window depth in [0,1]: 0 white, 1 (no hit) black.
    WindowDepth,
    /// Ids: each value its own colour, 0xFFFFFFFF (no hit) black.
    Id,
}

impl Meaning {
    /// What a frame channel holds, from its name and type.
    pub fn of_channel(channel: &str, pixel_type: ANARIDataType) -> Meaning {
        match (channel, pixel_type) {
            ("channel.normal", _) => Meaning::Normal,
            ("channel.windowDepth", _) => Meaning::WindowDepth,
            (_, ANARI_FLOAT32) => Meaning::Distance,
            (_, ANARI_UINT32) => Meaning::Id,
            _ => Meaning::Color,
        }
    }
}

fn read_f32(bytes: &[u8], index: usize) -> f32 {
    let start = index * 4;
    f32::from_ne_bytes([
        bytes[start],
        bytes[start + 1],
        bytes[start + 2],
        bytes[start + 3],
    ])
}

/// A well-spread colour for an id, so that neighbouring ids look different.
fn id_color(id: u32) -> [u8; 4] {
    if id == u32::MAX {
        return [0, 0, 0, 255];
    }
    let mut h = id.wrapping_mul(0x9E37_79B1);
    h ^= h >> 15;
    h = h.wrapping_mul(0x85EB_CA77);
    h ^= h >> 13;
    // Keep every component above 64 so that no id is mistaken for "no hit".
    let component = |shift: u32| 64 + ((h >> shift) & 0xFF) as u8 % 192;
    [component(0), component(8), component(16), 255]
}

/// Converts `width`×`height` pixels (rows bottom to top) into RGBA8 rows top to bottom.
/// `pixels` must hold exactly width·height elements of `pixel_type`.
pub fn to_rgba8(
    pixels: &[u8],
    width: u32,
    height: u32,
    pixel_type: ANARIDataType,
    meaning: Meaning,
) -> Result<Vec<u8>, String> {
    let (w, h) = (width as usize, height as usize);
    let count = w * h;
    let size = element_size(pixel_type).unwrap_or(0);
    if !WRITABLE_TYPES.contains(&pixel_type) || pixels.len() != count * size {
        return Err(format!(
            "{} pixels cannot be written as PNG (accepted: {})",
            type_name(pixel_type),
            type_list(WRITABLE_TYPES)
        ));
    }
    // Distances are scaled between the nearest and the farthest finite value of the image.
    let (near, far) = if meaning == Meaning::Distance && pixel_type == ANARI_FLOAT32 {
        (0..count)
            .map(|i| read_f32(pixels, i))
            .filter(|d| d.is_finite())
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), d| {
                (lo.min(d), hi.max(d))
            })
    } else {
        (0.0, 1.0)
    };
    let convert = |i: usize| -> [u8; 4] {
        let byte = |k: usize| pixels[i * size + k];
        let float = |k: usize| read_f32(pixels, i * (size / 4) + k);
        let linear8 = |v: u8| encode_srgb8(v as f32 / 255.0);
        match (pixel_type, meaning) {
            (ANARI_UFIXED8_RGBA_SRGB, _) => [byte(0), byte(1), byte(2), byte(3)],
            (ANARI_UFIXED8_RGB_SRGB, _) => [byte(0), byte(1), byte(2), 255],
            (ANARI_UFIXED8_VEC4, _) => [
                linear8(byte(0)),
                linear8(byte(1)),
                linear8(byte(2)),
                byte(3),
            ],
            (ANARI_UFIXED8_VEC3, _) => [linear8(byte(0)), linear8(byte(1)), linear8(byte(2)), 255],
            (ANARI_FLOAT32_VEC4 | ANARI_FLOAT32_VEC3, Meaning::Normal) => {
                let n = |k: usize| to_unorm8(float(k) * 0.5 + 0.5);
                [n(0), n(1), n(2), 255]
            }
            (ANARI_FLOAT32_VEC4, _) => [
                encode_srgb8(float(0)),
                encode_srgb8(float(1)),
                encode_srgb8(float(2)),
                to_unorm8(float(3)),
            ],
            (ANARI_FLOAT32_VEC3, _) => [
                encode_srgb8(float(0)),
                encode_srgb8(float(1)),
                encode_srgb8(float(2)),
                255,
            ],
            (ANARI_FLOAT32, Meaning::WindowDepth) => {
                let g = to_unorm8(1.0 - float(0));
                [g, g, g, 255]
            }
            (ANARI_FLOAT32, _) => {
                let d = float(0);
                if !d.is_finite() {
                    return [0, 0, 0, 255];
                }
                let span = far - near;
                let nearness = if span > 0.0 { (far - d) / span } else { 1.0 };
                // Nearest white, farthest still visibly above "no hit".
                let g = to_unorm8(0.15 + 0.85 * nearness);
                [g, g, g, 255]
            }
            (ANARI_UINT32, _) => id_color(u32::from_ne_bytes([byte(0), byte(1), byte(2), byte(3)])),
            _ => [0, 0, 0, 0],
        }
    };
    let mut out = Vec::new();
    out.try_reserve_exact(count * 4)
        .map_err(|_| format!("cannot allocate a {width}×{height} RGBA image"))?;
    for row in (0..h).rev() {
        for x in 0..w {
            out.extend_from_slice(&convert(row * w + x));
        }
    }
    Ok(out)
}

fn type_list(types: &[ANARIDataType]) -> String {
    types
        .iter()
        .map(|t| type_name(*t))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Writes RGBA8 rows (top to bottom) as a PNG file tagged sRGB.
fn write_png(path: &str, width: u32, height: u32, rgba: &[u8]) -> Result<(), String> {
    let file = File::create(path).map_err(|e| format!("cannot create '{path}': {e}"))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder
        .write_header()
        .map_err(|e| format!("cannot write '{path}': {e}"))?;
    writer
        .write_image_data(rgba)
        .map_err(|e| format!("cannot write '{path}': {e}"))?;
    writer
        .finish()
        .map_err(|e| format!("cannot write '{path}': {e}"))
}

/// Reports `text` as an error of `code` from `function` and returns the code.
fn fail(
    device: &Device,
    code: ANARIStatusCode,
    object: Option<&Object>,
    function: &str,
    text: String,
) -> ANARIStatusCode {
    device.error(code, object, format!("{function}: {text}"));
    code
}

/// Pixels to write: rows bottom to top, `width`·`height` elements of `pixel_type`.
struct Image<'a> {
    pixels: &'a [u8],
    width: u32,
    height: u32,
    pixel_type: ANARIDataType,
    meaning: Meaning,
}

/// Converts and writes; an I/O failure is an INVALID_OPERATION, a bad type INVALID_ARGUMENT.
fn convert_and_write(
    device: &Device,
    object: Option<&Object>,
    function: &str,
    path: &str,
    image: Image,
) -> ANARIStatusCode {
    let Image {
        pixels,
        width,
        height,
        pixel_type,
        meaning,
    } = image;
    let rgba = match to_rgba8(pixels, width, height, pixel_type, meaning) {
        Ok(rgba) => rgba,
        Err(text) => {
            return fail(
                device,
                ANARI_STATUS_INVALID_ARGUMENT,
                object,
                function,
                text,
            );
        }
    };
    match write_png(path, width, height, &rgba) {
        Ok(()) => ANARI_STATUS_NO_ERROR,
        Err(text) => fail(
            device,
            ANARI_STATUS_INVALID_OPERATION,
            object,
            function,
            text,
        ),
    }
}

/// Writes one channel of a rendered frame to a PNG file (waiting for the render in flight).
/// Colour is written as sRGB, depth as grey (nearest white, no hit black), ids as distinct
/// colours (no hit black), normals as (n + 1) / 2. The channel must not be mapped by the
/// application during the call. Returns ANARI_STATUS_NO_ERROR, or the code it reported through
/// the device's status callback.
#[unsafe(no_mangle)]
pub extern "C" fn cavetraceWriteFramePNG(
    device: ANARIDevice,
    frame: ANARIFrame,
    channel: *const c_char,
    path: *const c_char,
) -> ANARIStatusCode {
    const F: &str = "cavetraceWriteFramePNG";
    guard(F, device, ANARI_STATUS_UNKNOWN_ERROR, || {
        let Some(device) = device_of(F, device) else {
            return ANARI_STATUS_INVALID_ARGUMENT;
        };
        let Some(object) = device.resolve(F, frame as usize) else {
            return ANARI_STATUS_INVALID_ARGUMENT;
        };
        let Some(state) = &object.frame else {
            let text = format!("{} is not a frame", object.describe());
            return fail(
                &device,
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(&object),
                F,
                text,
            );
        };
        let (Some(channel), Some(path)) = (
            string_arg(&device, F, "channel", channel),
            string_arg(&device, F, "path", path),
        ) else {
            return ANARI_STATUS_INVALID_ARGUMENT;
        };
        let Some((pointer, width, height, pixel_type)) = state.map(&channel) else {
            let text = format!(
                "'{channel}' is not available: enable it with the frame parameter '{channel}' \
                 (an ANARI_DATA_TYPE), commit, and render first"
            );
            return fail(
                &device,
                ANARI_STATUS_INVALID_OPERATION,
                Some(&object),
                F,
                text,
            );
        };
        let bytes = width as usize * height as usize * element_size(pixel_type).unwrap_or(0);
        // SAFETY: a mapped channel holds width·height elements of its type and stays alive
        // until the unmap below.
        let pixels = unsafe { std::slice::from_raw_parts(pointer as *const u8, bytes) };
        let image = Image {
            pixels,
            width,
            height,
            pixel_type,
            meaning: Meaning::of_channel(&channel, pixel_type),
        };
        let status = convert_and_write(&device, Some(&object), F, &path, image);
        state.unmap(&channel);
        status
    })
}

/// Writes `width`×`height` pixels of `pixelType` (rows bottom to top, as ANARI frames store
/// them) to a PNG file. Accepts the colour types of channel.color and channel.albedo, ANARI_FLOAT32
/// (shown as distance) and ANARI_UINT32 (shown as ids). Returns ANARI_STATUS_NO_ERROR, or the
/// code it reported through the device's status callback.
#[unsafe(no_mangle)]
pub extern "C" fn cavetraceWriteImagePNG(
    device: ANARIDevice,
    path: *const c_char,
    width: u32,
    height: u32,
    pixel_type: ANARIDataType,
    pixels: *const c_void,
) -> ANARIStatusCode {
    const F: &str = "cavetraceWriteImagePNG";
    guard(F, device, ANARI_STATUS_UNKNOWN_ERROR, || {
        let Some(device) = device_of(F, device) else {
            return ANARI_STATUS_INVALID_ARGUMENT;
        };
        let Some(path) = string_arg(&device, F, "path", path) else {
            return ANARI_STATUS_INVALID_ARGUMENT;
        };
        if pixels.is_null() {
            let text = "'pixels' is NULL".to_string();
            return fail(&device, ANARI_STATUS_INVALID_ARGUMENT, None, F, text);
        }
        if width == 0 || height == 0 {
            let text = format!("the image size {width}×{height} is empty");
            return fail(&device, ANARI_STATUS_INVALID_ARGUMENT, None, F, text);
        }
        let Some(size) = element_size(pixel_type).filter(|_| WRITABLE_TYPES.contains(&pixel_type))
        else {
            let text = format!(
                "pixel type {} ({pixel_type}) cannot be written as PNG (accepted: {})",
                type_name(pixel_type),
                type_list(WRITABLE_TYPES)
            );
            return fail(&device, ANARI_STATUS_INVALID_ARGUMENT, None, F, text);
        };
        let Some(bytes) = (width as usize)
            .checked_mul(height as usize)
            .and_then(|n| n.checked_mul(size))
            .filter(|n| *n <= isize::MAX as usize)
        else {
            let text = format!("a {width}×{height} image overflows the address space");
            return fail(&device, ANARI_STATUS_OUT_OF_MEMORY, None, F, text);
        };
        // SAFETY: the application passes width·height elements of pixelType (API contract).
        let pixels = unsafe { std::slice::from_raw_parts(pixels as *const u8, bytes) };
        let meaning = if pixel_type == ANARI_FLOAT32 {
            Meaning::Distance
        } else if pixel_type == ANARI_UINT32 {
            Meaning::Id
        } else {
            Meaning::Color
        };
        let image = Image {
            pixels,
            width,
            height,
            pixel_type,
            meaning,
        };
        convert_and_write(&device, None, F, &path, image)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::array::srgb_to_linear;

    fn floats(values: &[f32]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_ne_bytes()).collect()
    }

    #[test]
    fn rows_are_flipped_to_top_first() {
        // 1×2 sRGB image: bottom row red, top row green.
        let pixels = [255, 0, 0, 255, 0, 255, 0, 255];
        let rgba = to_rgba8(&pixels, 1, 2, ANARI_UFIXED8_RGBA_SRGB, Meaning::Color).unwrap();
        assert_eq!(rgba, [0, 255, 0, 255, 255, 0, 0, 255]);
    }

    #[test]
    fn linear_floats_are_srgb_encoded() {
        let pixels = floats(&[0.5, 0.0, 1.0, 1.0]);
        let rgba = to_rgba8(&pixels, 1, 1, ANARI_FLOAT32_VEC4, Meaning::Color).unwrap();
        assert_eq!(rgba, [188, 0, 255, 255]);
        assert!((srgb_to_linear(188.0 / 255.0) - 0.5).abs() < 0.005);
    }

    #[test]
    fn distances_run_from_white_to_grey_and_misses_are_black() {
        let pixels = floats(&[1.0, 3.0, f32::INFINITY]);
        let rgba = to_rgba8(&pixels, 3, 1, ANARI_FLOAT32, Meaning::Distance).unwrap();
        assert_eq!(&rgba[0..4], &[255, 255, 255, 255]);
        assert_eq!(&rgba[4..8], &[38, 38, 38, 255]);
        assert_eq!(&rgba[8..12], &[0, 0, 0, 255]);
    }

    #[test]
    fn window_depth_and_normals_use_their_fixed_ranges() {
        let depth = floats(&[0.0, 1.0]);
        let rgba = to_rgba8(&depth, 2, 1, ANARI_FLOAT32, Meaning::WindowDepth).unwrap();
        assert_eq!(rgba, [255, 255, 255, 255, 0, 0, 0, 255]);
        let normal = floats(&[0.0, 1.0, -1.0]);
        let rgba = to_rgba8(&normal, 1, 1, ANARI_FLOAT32_VEC3, Meaning::Normal).unwrap();
        assert_eq!(rgba, [128, 255, 0, 255]);
    }

    #[test]
    fn ids_get_distinct_visible_colors_and_misses_are_black() {
        let ids: Vec<u8> = [0u32, 1, 2, u32::MAX]
            .iter()
            .flat_map(|v| v.to_ne_bytes())
            .collect();
        let rgba = to_rgba8(&ids, 4, 1, ANARI_UINT32, Meaning::Id).unwrap();
        let pixel = |i: usize| &rgba[i * 4..i * 4 + 4];
        assert_ne!(pixel(0), pixel(1));
        assert_ne!(pixel(1), pixel(2));
        assert!(pixel(0)[..3].iter().all(|c| *c >= 64));
        assert_eq!(pixel(3), &[0, 0, 0, 255]);
    }

    #[test]
    fn unsupported_types_and_wrong_lengths_are_refused() {
        let error = to_rgba8(&[0; 8], 1, 1, ANARI_FLOAT64, Meaning::Color).unwrap_err();
        assert!(error.contains("ANARI_FLOAT64"), "{error}");
        assert!(to_rgba8(&[0; 3], 1, 1, ANARI_UFIXED8_RGBA_SRGB, Meaning::Color).is_err());
    }
}
