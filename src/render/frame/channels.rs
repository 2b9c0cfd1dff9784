//! Frame channels: which channels a frame can produce, how each requested one is encoded
//! per tile, and the buffers a render writes them into.

use glam::{Vec3, Vec4};

use std::collections::HashMap;
use std::ops::Range;

use crate::device::datatype::*;
use crate::render::color::{srgb8_encoder, srgb8_rgba_encoder, to_snorm16, to_unorm8};
use crate::render::progressive::TileMap;

use super::records::TileRecords;
use super::{Inner, Output, RenderSetup, StartError};

/// The channels a frame can produce and the types each may be mapped as.
pub const CHANNELS: &[(&str, &[ANARIDataType])] = &[
    (
        "channel.color",
        &[
            ANARI_UFIXED8_RGBA_SRGB,
            ANARI_UFIXED8_VEC4,
            ANARI_FLOAT32_VEC4,
        ],
    ),
    ("channel.depth", &[ANARI_FLOAT32]),
    ("channel.primitiveId", &[ANARI_UINT32]),
    ("channel.objectId", &[ANARI_UINT32]),
    ("channel.instanceId", &[ANARI_UINT32]),
    (
        "channel.albedo",
        &[
            ANARI_UFIXED8_VEC3,
            ANARI_UFIXED8_RGB_SRGB,
            ANARI_FLOAT32_VEC3,
        ],
    ),
    ("channel.normal", &[ANARI_FLOAT32_VEC3, ANARI_FIXED16_VEC3]),
    ("channel.windowDepth", &[ANARI_FLOAT32]),
    ("channel.parallax", &[ANARI_FLOAT32]),
];

/// What a channel holds.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum ChannelKind {
    Color,
    Depth,
    WindowDepth,
    PrimitiveId,
    ObjectId,
    InstanceId,
    Albedo,
    Normal,
    Parallax,
}

impl ChannelKind {
    pub(super) fn of(name: &str) -> Option<ChannelKind> {
        Some(match name {
            "channel.color" => ChannelKind::Color,
            "channel.depth" => ChannelKind::Depth,
            "channel.windowDepth" => ChannelKind::WindowDepth,
            "channel.primitiveId" => ChannelKind::PrimitiveId,
            "channel.objectId" => ChannelKind::ObjectId,
            "channel.instanceId" => ChannelKind::InstanceId,
            "channel.albedo" => ChannelKind::Albedo,
            "channel.normal" => ChannelKind::Normal,
            "channel.parallax" => ChannelKind::Parallax,
            _ => return None,
        })
    }
}

/// How one requested channel is encoded: what it holds, as which type.
#[derive(Clone, Copy, Debug)]
pub(super) struct ChannelFormat {
    pub(super) kind: ChannelKind,
    pub(super) data_type: ANARIDataType,
    pub(super) pixel_bytes: usize,
}

/// `values` as native-endian bytes (`B` = 4·`N`).
#[inline(always)]
pub(super) fn f32_bytes<const N: usize, const B: usize>(values: [f32; N]) -> [u8; B] {
    let mut bytes = [0; B];
    for (chunk, value) in bytes.chunks_exact_mut(4).zip(values) {
        chunk.copy_from_slice(&value.to_ne_bytes());
    }
    bytes
}

impl ChannelFormat {
    /// Writes `pixel(k)` as pixel `k` of `out` (N bytes each, which must be the type's size).
    #[inline(always)]
    pub(super) fn encode_pixels<const N: usize>(
        &self,
        out: &mut [u8],
        pixel: impl Fn(usize) -> [u8; N],
    ) {
        debug_assert_eq!(N, self.pixel_bytes, "pixel size of {:?}", self.data_type);
        for (k, chunk) in out.chunks_exact_mut(N).enumerate() {
            chunk.copy_from_slice(&pixel(k));
        }
    }

    /// Writes `encode(colors[k])` as pixel `k` of `out` (N bytes each, the type's size): the
    /// colours walked beside the pixels, with no bounds check per pixel.
    #[inline(always)]
    fn encode_colors<const N: usize>(
        &self,
        out: &mut [u8],
        colors: &[Vec4],
        encode: impl Fn(Vec4) -> [u8; N],
    ) {
        debug_assert_eq!(N, self.pixel_bytes, "pixel size of {:?}", self.data_type);
        for (chunk, color) in out.chunks_exact_mut(N).zip(colors) {
            chunk.copy_from_slice(&encode(*color));
        }
    }

    /// Encodes the pixels of a tile into `rows` (`pixel_bytes` each, in the order of
    /// `colors`, `row_pixels` to a row): `colors` are their final colours, `records` the other
    /// channels' values. The match on the type is made once per tile, not per pixel or row.
    pub(super) fn encode(
        &self,
        colors: &[Vec4],
        records: &TileRecords,
        row_pixels: usize,
        rows: &mut impl TileRows,
    ) {
        let pixels = colors.len();
        let mut each_row = |write: &mut dyn FnMut(&mut [u8], Range<usize>)| {
            let mut start = 0;
            for row in 0.. {
                if start >= pixels {
                    break;
                }
                let end = (start + row_pixels).min(pixels);
                write(rows.row(row, (end - start) * self.pixel_bytes), start..end);
                start = end;
            }
        };
        let float = |values: &[f32], k: usize, nothing: f32| {
            f32_bytes::<1, 4>([values.get(k).copied().unwrap_or(nothing)])
        };
        let id = |values: &[u32], k: usize| values.get(k).map_or(u32::MAX, |v| *v).to_ne_bytes();
        let vector =
            |values: &[Vec3], k: usize| values.get(k).map_or(Vec3::ZERO, |v| *v).to_array();
        match (self.kind, self.data_type) {
            (ChannelKind::Color, ANARI_UFIXED8_RGBA_SRGB) => {
                let srgba = srgb8_rgba_encoder();
                each_row(&mut |out, range| self.encode_colors(out, &colors[range], srgba))
            }
            (ChannelKind::Color, ANARI_UFIXED8_VEC4) => each_row(&mut |out, range| {
                self.encode_colors(out, &colors[range], |color| color.to_array().map(to_unorm8))
            }),
            (ChannelKind::Color, _) => each_row(&mut |out, range| {
                self.encode_colors(out, &colors[range], |color| {
                    f32_bytes::<4, 16>(color.to_array())
                })
            }),
            (ChannelKind::Depth, _) => match records.depth.get(..pixels) {
                // Every pixel recorded (the usual case): a plain copy.
                Some(depths) => {
                    debug_assert_eq!(self.pixel_bytes, 4, "pixel size of {:?}", self.data_type);
                    each_row(&mut |out, range| {
                        for (chunk, depth) in out.chunks_exact_mut(4).zip(&depths[range]) {
                            chunk.copy_from_slice(&depth.to_ne_bytes());
                        }
                    })
                }
                None => each_row(&mut |out, range| {
                    self.encode_pixels(out, |k| {
                        float(&records.depth, range.start + k, f32::INFINITY)
                    })
                }),
            },
            (ChannelKind::WindowDepth, _) => each_row(&mut |out, range| {
                self.encode_pixels(out, |k| float(&records.window_depth, range.start + k, 1.0))
            }),
            (ChannelKind::Parallax, _) => each_row(&mut |out, range| {
                self.encode_pixels(out, |k| float(&records.parallax, range.start + k, f32::NAN))
            }),
            (ChannelKind::PrimitiveId, _) => each_row(&mut |out, range| {
                self.encode_pixels(out, |k| id(&records.primitive_id, range.start + k))
            }),
            (ChannelKind::ObjectId, _) => each_row(&mut |out, range| {
                self.encode_pixels(out, |k| id(&records.object_id, range.start + k))
            }),
            (ChannelKind::InstanceId, _) => each_row(&mut |out, range| {
                self.encode_pixels(out, |k| id(&records.instance_id, range.start + k))
            }),
            (ChannelKind::Albedo, data_type) => each_row(&mut |out, range| {
                let albedo = |k: usize| vector(&records.albedo, range.start + k);
                match data_type {
                    ANARI_UFIXED8_RGB_SRGB => {
                        let srgb = srgb8_encoder();
                        self.encode_pixels(out, |k| albedo(k).map(srgb))
                    }
                    ANARI_UFIXED8_VEC3 => self.encode_pixels(out, |k| albedo(k).map(to_unorm8)),
                    _ => self.encode_pixels(out, |k| f32_bytes::<3, 12>(albedo(k))),
                }
            }),
            (ChannelKind::Normal, data_type) => each_row(&mut |out, range| {
                let normal = |k: usize| vector(&records.normal, range.start + k);
                match data_type {
                    ANARI_FIXED16_VEC3 => self.encode_pixels(out, |k| {
                        let [x, y, z] = normal(k).map(|v| to_snorm16(v).to_ne_bytes());
                        [x[0], x[1], y[0], y[1], z[0], z[1]]
                    }),
                    _ => self.encode_pixels(out, |k| f32_bytes::<3, 12>(normal(k))),
                }
            }),
        }
    }
}

/// Where a tile's encoded rows go: a buffer of the tile alone, or the frame's own rows.
pub(super) trait TileRows {
    /// The `bytes` bytes of the tile's row `row`.
    fn row(&mut self, row: usize, bytes: usize) -> &mut [u8];
}

/// A tile encoded into a buffer of its own, row after row.
pub(super) struct PackedRows<'a> {
    pub(super) bytes: &'a mut [u8],
    pub(super) row_bytes: usize,
}

impl TileRows for PackedRows<'_> {
    #[inline(always)]
    fn row(&mut self, row: usize, bytes: usize) -> &mut [u8] {
        &mut self.bytes[row * self.row_bytes..][..bytes]
    }
}

/// A channel's pixel buffer, written by the workers of a render straight from their tiles:
/// each tile's rows go to their place in the frame with no tile buffer and no copy.
pub(super) struct FrameTarget {
    start: *mut u8,
    len: usize,
    pixel_bytes: usize,
    row_bytes: usize,
}

// SAFETY: a FrameTarget only hands out the rows of tiles through `TileInFrame`, whose creation
// requires that no two of them cover the same pixel and that nothing else touches the buffer
// while they live; threads sharing it write disjoint bytes.
unsafe impl Send for FrameTarget {}
// SAFETY: as for Send.
unsafe impl Sync for FrameTarget {}

impl FrameTarget {
    /// `channel`'s buffer for a frame `frame_width` pixels wide. The buffer must not be
    /// moved, resized or read while tiles are written through the target.
    pub(super) fn of(channel: &mut Channel, frame_width: u32) -> FrameTarget {
        let pixel_bytes = channel.format.pixel_bytes;
        FrameTarget {
            start: channel.bytes.as_mut_ptr(),
            len: channel.bytes.len(),
            pixel_bytes,
            row_bytes: frame_width as usize * pixel_bytes,
        }
    }

    /// The rows of the tile `tile_width` × `tile_height` pixels whose first pixel is (x0, y0).
    /// Panics when the tile's columns leave the frame: its rows would run on into the next
    /// frame row, another tile's pixels.
    ///
    /// # Safety
    /// While the returned value lives, no other `TileInFrame` of this target covers any of
    /// its pixels and nothing else reads or writes the buffer.
    pub(super) unsafe fn tile(
        &self,
        x0: u32,
        y0: u32,
        tile_width: u32,
        tile_height: u32,
    ) -> TileInFrame<'_> {
        let (column, row_bytes) = (
            x0 as usize * self.pixel_bytes,
            tile_width as usize * self.pixel_bytes,
        );
        assert!(
            column + row_bytes <= self.row_bytes,
            "tile columns from {x0}, {tile_width} wide, outside the frame"
        );
        TileInFrame {
            target: self,
            first: y0 as usize * self.row_bytes + column,
            row_bytes,
            rows: tile_height as usize,
        }
    }
}

/// One tile's rows in a [`FrameTarget`].
pub(super) struct TileInFrame<'a> {
    target: &'a FrameTarget,
    /// Byte offset of the tile's first pixel.
    first: usize,
    /// Bytes of one of the tile's rows.
    row_bytes: usize,
    /// The tile's rows.
    rows: usize,
}

impl TileRows for TileInFrame<'_> {
    #[inline(always)]
    fn row(&mut self, row: usize, bytes: usize) -> &mut [u8] {
        let start = self.first + row * self.target.row_bytes;
        assert!(
            row < self.rows && bytes <= self.row_bytes && start + bytes <= self.target.len,
            "tile row {row} outside its tile or the frame"
        );
        // SAFETY: the bytes lie inside the buffer and inside one of this tile's rows, whose
        // columns lie inside the frame (both asserted), so no other live TileInFrame covers
        // them (`FrameTarget::tile`'s contract), and the slice borrows `self` mutably, so this
        // tile hands out one row at a time.
        unsafe { std::slice::from_raw_parts_mut(self.target.start.add(start), bytes) }
    }
}

/// One requested channel of a render with its pixels. Tiles are encoded by the threads that
/// render them, straight into the frame's rows ([`FrameTarget`]) or copied in row by row, so a
/// finished render needs no encoding pass.
pub(super) struct Channel {
    pub(super) name: &'static str,
    pub(super) format: ChannelFormat,
    pub(super) bytes: Vec<u8>,
}

impl Channel {
    /// Copies the encoded pixels of `map`'s tile (in its order) to their places in a frame
    /// `frame_width` pixels wide.
    pub(super) fn write_area(&mut self, map: &impl TileMap, frame_width: u32, tile: &[u8]) {
        let area = map.area();
        if let Some((x0, y0)) = map.rectangle_origin() {
            self.write_tile(x0, y0, area.s1 - area.s0, frame_width, tile);
            return;
        }
        // The usual sizes as constants in the inlined body: each copy becomes a move or two,
        // where a call to copy a few bytes cost more than the rest of the loop.
        match self.format.pixel_bytes {
            4 => self.scatter(map, frame_width, tile, 4),
            12 => self.scatter(map, frame_width, tile, 12),
            16 => self.scatter(map, frame_width, tile, 16),
            bytes => self.scatter(map, frame_width, tile, bytes),
        }
    }

    /// [`Channel::write_area`] for `bytes`-byte pixels, row by row: a row of points that is a
    /// run of consecutive pixels of one frame row (an eye's row of a rowInterleaved frame) in
    /// one copy, other rows point by point (a map look-up, a bounds check and a store each).
    #[inline(always)]
    fn scatter(&mut self, map: &impl TileMap, frame_width: u32, tile: &[u8], bytes: usize) {
        let area = map.area();
        let row_bytes = (area.s1 - area.s0) as usize * bytes;
        for (t, sources) in (area.t0..area.t1).zip(tile.chunks_exact(row_bytes)) {
            if let Some(row) = map.point_row(t) {
                let start = (row.y as usize * frame_width as usize + row.x as usize) * bytes;
                let length = row.count as usize * bytes;
                if let Some(target) = self.bytes.get_mut(start..start + length) {
                    target.copy_from_slice(&sources[..length]);
                }
                continue;
            }
            for (s, source) in (area.s0..).zip(sources.chunks_exact(bytes)) {
                if map.skips(s, t) {
                    continue;
                }
                let (x, y) = map.pixel(s, t);
                let start = (y as usize * frame_width as usize + x as usize) * bytes;
                if let Some(target) = self.bytes.get_mut(start..start + bytes) {
                    target.copy_from_slice(source);
                }
            }
        }
    }

    /// Copies a tile encoded by [`ChannelFormat::encode`] (`tile_width` pixels per row, rows
    /// from `y0` up) to its place in a frame `frame_width` pixels wide.
    pub(super) fn write_tile(
        &mut self,
        x0: u32,
        y0: u32,
        tile_width: u32,
        frame_width: u32,
        tile: &[u8],
    ) {
        let row_bytes = tile_width as usize * self.format.pixel_bytes;
        for (row, source) in tile.chunks_exact(row_bytes).enumerate() {
            let start = ((y0 as usize + row) * frame_width as usize + x0 as usize)
                * self.format.pixel_bytes;
            if let Some(target) = self.bytes.get_mut(start..start + row_bytes) {
                target.copy_from_slice(source);
            }
        }
    }
}

/// Bytes of `pixels` pixels of `pixel_bytes` bytes, or OutOfMemory when that overflows.
pub(super) fn buffer_bytes(pixels: usize, pixel_bytes: usize) -> Result<usize, StartError> {
    pixels
        .checked_mul(pixel_bytes)
        .ok_or(StartError::OutOfMemory)
}

/// Bytes a render will allocate: its channels and accumulation sum, less the buffers of the
/// last render it can reuse (same size and type).
pub(super) fn new_buffer_bytes(setup: &RenderSetup, inner: &Inner) -> Result<u64, StartError> {
    let pixels = setup.width as usize * setup.height as usize;
    let same_size = |w: u32, h: u32| w == setup.width && h == setup.height;
    let previous = inner
        .output
        .as_ref()
        .filter(|o| same_size(o.width, o.height));
    let mut bytes = 0u64;
    for (&name, &data_type) in &setup.channels {
        let reused = previous
            .and_then(|o| o.channels.get(name))
            .is_some_and(|(t, _)| *t == data_type);
        if !reused {
            let pixel_bytes = element_size(data_type).unwrap_or(0);
            bytes = bytes.saturating_add(buffer_bytes(pixels, pixel_bytes)? as u64);
        }
    }
    let sum_reused = matches!(&inner.accumulation, Some((_, _, _, w, h)) if same_size(*w, *h));
    if setup.accumulate && !sum_reused {
        let sum = buffer_bytes(pixels, std::mem::size_of::<Vec4>())?;
        bytes = bytes.saturating_add(sum as u64);
    }
    Ok(bytes)
}

/// The channels of a render: the previous render's buffers when nobody has them mapped and
/// they fit (a head-tracked application renders the same frame again and again), otherwise
/// new ones.
pub(super) fn allocate_channels(
    setup: &RenderSetup,
    previous: Option<Output>,
) -> Result<Vec<Channel>, StartError> {
    let pixels = setup.width as usize * setup.height as usize;
    let mut reusable = match previous {
        Some(output) if output.width == setup.width && output.height == setup.height => {
            output.channels
        }
        _ => HashMap::new(),
    };
    let mut channels = Vec::new();
    for (&name, &data_type) in &setup.channels {
        let (Some(kind), Some(pixel_bytes)) = (ChannelKind::of(name), element_size(data_type))
        else {
            continue;
        };
        let bytes = match reusable.remove(name) {
            Some((previous_type, bytes)) if previous_type == data_type => bytes,
            _ => {
                let length = buffer_bytes(pixels, pixel_bytes)?;
                let mut bytes = Vec::new();
                bytes
                    .try_reserve_exact(length)
                    .map_err(|_| StartError::OutOfMemory)?;
                bytes.resize(length, 0);
                bytes
            }
        };
        channels.push(Channel {
            name,
            format: ChannelFormat {
                kind,
                data_type,
                pixel_bytes,
            },
            bytes,
        });
    }
    Ok(channels)
}

/// Smallest and largest of native-endian FLOAT32 pixels, NaNs (no hit) left out; NaN for both
/// when every pixel is NaN.
pub(super) fn value_range(bytes: &[u8]) -> [f32; 2] {
    let (low, high) = bytes
        .chunks_exact(4)
        .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
        .filter(|v| !v.is_nan())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(low, high), v| {
            (low.min(v), high.max(v))
        });
    if low > high {
        [f32::NAN; 2]
    } else {
        [low, high]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(kind: ChannelKind, data_type: ANARIDataType, pixels: usize) -> Channel {
        let pixel_bytes = element_size(data_type).expect("a channel type");
        Channel {
            name: "channel",
            format: ChannelFormat {
                kind,
                data_type,
                pixel_bytes,
            },
            bytes: vec![0xab; pixels * pixel_bytes],
        }
    }

    #[test]
    fn tiles_encoded_into_the_frame_land_on_their_pixels_as_copied_tiles_do() {
        // A 7×5 frame in tiles of 3×2 (the last column and row narrower), pixel (x, y)'s
        // depth y·7 + x, its primitive id 1000 more, its colour from the same number.
        let (width, height) = (7u32, 5u32);
        let pixels = (width * height) as usize;
        let kinds = [
            (ChannelKind::Color, ANARI_UFIXED8_RGBA_SRGB),
            (ChannelKind::Color, ANARI_FLOAT32_VEC4),
            (ChannelKind::Depth, ANARI_FLOAT32),
            (ChannelKind::PrimitiveId, ANARI_UINT32),
        ];
        let color_of =
            |index: u32| Vec4::new(index as f32 / 40.0, 0.5, 1.0 - index as f32 / 40.0, 1.0);
        for (kind, data_type) in kinds {
            let mut direct = channel(kind, data_type, pixels);
            let mut copied = channel(kind, data_type, pixels);
            let format = direct.format;
            let target = FrameTarget::of(&mut direct, width);
            for y0 in (0..height).step_by(2) {
                for x0 in (0..width).step_by(3) {
                    let (x1, y1) = ((x0 + 3).min(width), (y0 + 2).min(height));
                    let index = |k: u32| (y0 + k / (x1 - x0)) * width + x0 + k % (x1 - x0);
                    let count = (x1 - x0) * (y1 - y0);
                    let colors: Vec<Vec4> = (0..count).map(|k| color_of(index(k))).collect();
                    let mut records = TileRecords::default();
                    records.depth = (0..count).map(|k| index(k) as f32).collect();
                    records.primitive_id = (0..count).map(|k| 1000 + index(k)).collect();
                    let row_pixels = (x1 - x0) as usize;
                    // SAFETY: the tiles are disjoint and the rows are written one tile at a
                    // time; `direct` is read only after the last.
                    let mut rows = unsafe { target.tile(x0, y0, x1 - x0, y1 - y0) };
                    format.encode(&colors, &records, row_pixels, &mut rows);
                    let mut tile = vec![0; colors.len() * format.pixel_bytes];
                    let row_bytes = tile.len();
                    let mut packed = PackedRows {
                        bytes: &mut tile,
                        row_bytes,
                    };
                    format.encode(&colors, &records, colors.len(), &mut packed);
                    copied.write_tile(x0, y0, x1 - x0, width, &tile);
                }
            }
            assert_eq!(direct.bytes, copied.bytes, "{kind:?} {data_type}");
            let pixel =
                |index: usize| &direct.bytes[index * format.pixel_bytes..][..format.pixel_bytes];
            for index in 0..pixels {
                let expected: Vec<u8> = match kind {
                    ChannelKind::Depth => (index as f32).to_ne_bytes().to_vec(),
                    ChannelKind::PrimitiveId => (1000 + index as u32).to_ne_bytes().to_vec(),
                    _ if data_type == ANARI_FLOAT32_VEC4 => {
                        f32_bytes::<4, 16>(color_of(index as u32).to_array()).to_vec()
                    }
                    _ => srgb8_rgba_encoder()(color_of(index as u32)).to_vec(),
                };
                assert_eq!(pixel(index), expected, "{kind:?} pixel {index}");
            }
        }
    }

    #[test]
    #[should_panic(expected = "outside the frame")]
    fn a_tile_reaching_past_the_frames_right_edge_is_refused() {
        // Columns 5..8 of a 7-pixel-wide frame: row 0's last pixel would be row 1's first.
        let mut frame = channel(ChannelKind::Depth, ANARI_FLOAT32, 7 * 2);
        let target = FrameTarget::of(&mut frame, 7);
        // SAFETY: the only tile of this target; the call panics before any row is handed out.
        let _rows = unsafe { target.tile(5, 0, 3, 1) };
    }

    #[test]
    fn interleaved_tiles_land_on_the_pixels_a_point_by_point_copy_gives() {
        // Odd frame sizes, so that a lattice's last row or column leaves the frame; tiles of
        // 3, 8 or 17 × 2 points; pixels of 4, 8, 12 and 16 bytes; each point's bytes numbered
        // by point so that any misplaced one shows.
        use crate::camera::PixelSet;
        use crate::render::interleave::{InterleavedTile, lattice_size};
        for (width, height, tile_width) in [
            (7u32, 5u32, 3u32),
            (8, 6, 3),
            (9, 7, 3),
            (37, 5, 17),
            (40, 4, 8),
        ] {
            for set in [0, 1].map(PixelSet::Rows).into_iter().chain(
                [0, 1]
                    .into_iter()
                    .flat_map(|p| [PixelSet::Columns(p), PixelSet::Checkerboard(p)]),
            ) {
                for data_type in [
                    ANARI_FLOAT32,
                    ANARI_FLOAT32_VEC2,
                    ANARI_FLOAT32_VEC3,
                    ANARI_FLOAT32_VEC4,
                ] {
                    let pixels = (width * height) as usize;
                    let mut written = channel(ChannelKind::Depth, data_type, pixels);
                    let mut expected = written.bytes.clone();
                    let bytes = written.format.pixel_bytes;
                    let (lattice_width, lattice_height) = lattice_size(set, width, height);
                    for t0 in (0..lattice_height).step_by(2) {
                        for s0 in (0..lattice_width).step_by(tile_width as usize) {
                            let (s1, t1) = (
                                (s0 + tile_width).min(lattice_width),
                                (t0 + 2).min(lattice_height),
                            );
                            let tile_map =
                                InterleavedTile::new(set, (s0, t0), (s1, t1), (width, height));
                            let points: Vec<(u32, u32)> = (t0..t1)
                                .flat_map(|t| (s0..s1).map(move |s| (s, t)))
                                .collect();
                            let tile: Vec<u8> = points
                                .iter()
                                .flat_map(|&(s, t)| {
                                    let number = 1 + t * lattice_width + s;
                                    (0..bytes).map(move |k| (number as usize * 31 + k) as u8)
                                })
                                .collect();
                            written.write_area(&tile_map, width, &tile);
                            for (&(s, t), source) in points.iter().zip(tile.chunks_exact(bytes)) {
                                if tile_map.skips(s, t) {
                                    continue;
                                }
                                let (x, y) = tile_map.pixel(s, t);
                                let start = (y * width + x) as usize * bytes;
                                expected[start..start + bytes].copy_from_slice(source);
                            }
                        }
                    }
                    assert_eq!(
                        written.bytes, expected,
                        "{width}x{height} {set:?} {data_type}"
                    );
                }
            }
        }
    }
}
