//! Volumes: `transferFunction1D` maps a spatial field through a colour and opacity table. This
//! file holds the committed volume and the ray march (the informative algorithm of the ANARI
//! specification): samples one every half cell, and a sample of opacity `o` over a step of
//! world length `s` passes `(1 − o)^(s / unitDistance)` of the light behind it. Stretches over
//! macrocells the transfer function makes transparent are skipped, and steps grow where it
//! makes them nearly transparent (see [`Stepping`]). The fast renderer draws the
//! march as emission–absorption ([`integrate`]); the default renderer lights it
//! ([`crate::render::volume_lighting`]).

use std::sync::Arc;

use glam::{Affine3A, Vec3, Vec4};

use crate::device::Device;
use crate::device::array::ArrayStore;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::params::ParamValue;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::attributes::{VALUE_ELEMENT_TYPES, read_values};
use crate::scene::field::Field;
use crate::scene::macrocells::ValueRange;

pub const TRANSFER_FUNCTION1D: ObjectSpec = ObjectSpec::new(
    ANARI_VOLUME,
    "transferFunction1D",
    "a spatial field coloured by a 1D transfer function, rendered as emitting and absorbing \
     particles",
    &[
        ParamSpec::new(
            "value",
            &[ANARI_SPATIAL_FIELD],
            "spatial field sampled for the scalar values",
        )
        .required(),
        ParamSpec::new(
            "valueRange",
            &[ANARI_FLOAT32_BOX1, ANARI_FLOAT64_BOX1],
            "field values are clamped to this range, whose ends map to the first and last \
             table entries",
        )
        .default(SpecValue::Floats(&[0.0, 1.0])),
        ParamSpec::new(
            "color",
            &[ANARI_FLOAT32_VEC4, ANARI_FLOAT32_VEC3, ANARI_ARRAY1D],
            "colour (uniform, or a table over valueRange); alpha multiplies the opacity",
        )
        .default(SpecValue::Floats(&[1.0, 1.0, 1.0, 1.0]))
        .elements(VALUE_ELEMENT_TYPES),
        ParamSpec::new(
            "opacity",
            &[ANARI_FLOAT32, ANARI_ARRAY1D],
            "opacity (uniform, or a table over valueRange)",
        )
        .default(SpecValue::Float(1.0))
        .elements(&[ANARI_FLOAT32]),
        ParamSpec::new(
            "unitDistance",
            &[ANARI_FLOAT32],
            "world distance over which 'opacity' of the light is absorbed",
        )
        .default(SpecValue::Float(1.0)),
        ParamSpec::new("visible", &[ANARI_BOOL], "whether the volume is rendered")
            .default(SpecValue::Bool(true)),
        ParamSpec::new("id", &[ANARI_UINT32], "user id written to channel.objectId")
            .default(SpecValue::UInt(u32::MAX)),
    ],
)
.extensions(&["ANARI_KHR_VOLUME_TRANSFER_FUNCTION1D"]);

/// Once less than this fraction of the light behind gets through, marching stops and the rest
/// counts as absorbed.
const OPAQUE_TRANSMITTANCE: f32 = 1e-3;
/// Bound on the samples of one ray between two volume boundaries.
const MAX_STEPS: f32 = 65536.0;
/// Adaptive steps: the most optical depth one step may cross where its macrocell is the most
/// opaque it can be (a worst-case opacity per step of 1 − e^−0.02 ≈ 2 %).
const ADAPTIVE_OPTICAL_DEPTH: f32 = 0.02;
/// Adaptive steps: the longest step, in base steps (half cells): half a macrocell.
const MAX_STEP_MULTIPLE: u32 = 8;

/// How a ray march places its samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stepping {
    /// One sample per base step (half a cell) from entry to exit.
    Fixed,
    /// The `Fixed` samples, less those in macrocells the transfer function makes transparent
    /// (which are exactly samples of opacity 0: the result is the same, bit for bit).
    SkipEmpty,
    /// `SkipEmpty`, and in the other macrocells steps of several base steps where their most
    /// opaque value keeps a step's optical depth under `ADAPTIVE_OPTICAL_DEPTH` (each sample's
    /// opacity corrected for its step's length). Where a volume is dense, or volumes overlap,
    /// the base steps remain.
    Adaptive,
}

impl Stepping {
    /// What the renderers use.
    pub(crate) const DEFAULT: Stepping = Stepping::Adaptive;
}

/// The committed colour and opacity mapping of a `transferFunction1D` volume.
#[derive(Debug)]
pub struct TransferFunction {
    /// channel.objectId value.
    pub id: u32,
    value_range: (f32, f32),
    /// One entry: uniform colour. Linear RGB plus alpha.
    colors: Vec<Vec4>,
    /// One entry: uniform opacity.
    opacities: Vec<f32>,
    unit_distance: f32,
    /// `visible_before[b]`: how many of the first `b` of `OPACITY_BINS` equal stretches of
    /// [0, 1] (the normalised value) may have a non-zero opacity.
    visible_before: Vec<u32>,
    /// The largest opacity each of those stretches may take (1 where unknown).
    opacity_bounds: Vec<f32>,
}

/// Stretches of the normalised value range the transfer function's visibility is kept for.
const OPACITY_BINS: usize = 256;

/// Largest magnitude a piecewise-linear table (ends at 0 and 1) takes in each of
/// `OPACITY_BINS` equal stretches of [0, 1]: at the stretch's ends or at a table entry inside
/// it. NaN counts as infinite.
fn bin_bounds(table: &[f32]) -> Vec<f32> {
    let magnitude = |v: f32| if v.is_nan() { f32::INFINITY } else { v.abs() };
    let at = |x: f32| magnitude(lookup(table, x, |a, b, f| a + (b - a) * f));
    let mut bounds: Vec<f32> = (0..OPACITY_BINS)
        .map(|b| {
            let x = b as f32 / OPACITY_BINS as f32;
            at(x).max(at((b + 1) as f32 / OPACITY_BINS as f32))
        })
        .collect();
    let last = table.len().saturating_sub(1).max(1) as f32;
    for (k, &entry) in table.iter().enumerate() {
        let bin = ((k as f32 / last * OPACITY_BINS as f32) as usize).min(OPACITY_BINS - 1);
        bounds[bin] = bounds[bin].max(magnitude(entry));
    }
    bounds
}

/// Linear interpolation in a table whose ends sit at `x` = 0 and 1 (`x` in [0, 1]).
#[inline]
fn lookup<T>(table: &[T], x: f32, lerp: impl Fn(T, T, f32) -> T) -> T
where
    T: Copy,
{
    let last = table.len() - 1;
    let position = x * last as f32;
    let lower = (position as usize).min(last);
    let upper = (lower + 1).min(last);
    lerp(table[lower], table[upper], position - lower as f32)
}

impl TransferFunction {
    pub fn new(
        id: u32,
        value_range: (f32, f32),
        colors: Vec<Vec4>,
        opacities: Vec<f32>,
        unit_distance: f32,
    ) -> Option<TransferFunction> {
        let valid = !colors.is_empty()
            && !opacities.is_empty()
            && value_range.0.is_finite()
            && value_range.1.is_finite()
            && unit_distance.is_finite()
            && unit_distance > 0.0;
        if !valid {
            return None;
        }
        let alphas: Vec<f32> = colors.iter().map(|c| c.w).collect();
        let mut visible_before = vec![0u32; OPACITY_BINS + 1];
        let mut opacity_bounds = vec![0.0f32; OPACITY_BINS];
        for (b, (alpha, opacity)) in bin_bounds(&alphas)
            .into_iter()
            .zip(bin_bounds(&opacities))
            .enumerate()
        {
            // Opacity is alpha × opacity, clamped: zero wherever either bound is.
            let visible = alpha > 0.0 && opacity > 0.0;
            visible_before[b + 1] = visible_before[b] + u32::from(visible);
            if visible {
                let bound = alpha * opacity;
                opacity_bounds[b] = if bound.is_nan() { 1.0 } else { bound.min(1.0) };
            }
        }
        Some(TransferFunction {
            id,
            value_range,
            colors,
            opacities,
            unit_distance,
            visible_before,
            opacity_bounds,
        })
    }

    /// Whether any value in `range` (lowest, highest; empty when lowest > highest) may be
    /// classified with a non-zero opacity. Conservative: the range is widened by a few units
    /// in the last place (interpolated samples may round past their vertices) and by one bin.
    pub fn may_be_visible(&self, range: ValueRange) -> bool {
        self.bins_of(range)
            .is_some_and(|(first, last)| self.visible_before[last + 1] > self.visible_before[first])
    }

    /// The largest opacity any value in `range` may be classified with, widened as
    /// [`TransferFunction::may_be_visible`] widens: 0 where that finds nothing visible.
    pub fn max_opacity(&self, range: ValueRange) -> f32 {
        match self.bins_of(range) {
            Some((first, last)) if self.visible_before[last + 1] > self.visible_before[first] => {
                self.opacity_bounds[first..=last]
                    .iter()
                    .fold(0.0, |a, &b| a.max(b))
            }
            _ => 0.0,
        }
    }

    /// First and last of the `OPACITY_BINS` a value range (lowest, highest) may fall in,
    /// widened by a few units in the last place and one bin; `None` for an empty range.
    fn bins_of(&self, (lowest, highest): ValueRange) -> Option<(usize, usize)> {
        if lowest > highest || lowest.is_nan() || highest.is_nan() {
            return None;
        }
        if !lowest.is_finite() || !highest.is_finite() {
            return Some((0, OPACITY_BINS - 1));
        }
        let slack = 16.0 * f32::EPSILON;
        let ends = [
            self.normalized(lowest - lowest.abs() * slack),
            self.normalized(highest + highest.abs() * slack),
        ];
        let (x0, x1) = (ends[0].min(ends[1]), ends[0].max(ends[1]));
        let bin = |x: f32| (x * OPACITY_BINS as f32) as usize;
        let first = bin(x0).saturating_sub(1).min(OPACITY_BINS - 1);
        let last = (bin(x1) + 1).min(OPACITY_BINS - 1);
        Some((first, last))
    }

    /// Position of a field value in valueRange, clamped to [0, 1]; NaN stays NaN. A reversed
    /// range (first end above the second) reverses the mapping.
    fn normalized(&self, value: f32) -> f32 {
        let (lo, hi) = self.value_range;
        if hi != lo {
            ((value - lo) / (hi - lo)).clamp(0.0, 1.0)
        } else if value.is_nan() {
            value
        } else if value > lo {
            1.0
        } else {
            0.0
        }
    }

    /// Colour and final opacity (colour alpha × opacity, in [0, 1]) for a field value. NaN
    /// values are empty space.
    #[inline]
    pub fn classify(&self, value: f32) -> (Vec3, f32) {
        let x = self.normalized(value);
        if x.is_nan() {
            return (Vec3::ZERO, 0.0);
        }
        let color = lookup(&self.colors, x, |a, b, f| a.lerp(b, f));
        let opacity = color.w * lookup(&self.opacities, x, |a, b, f| a + (b - a) * f);
        // A NaN table entry reads as transparent.
        let opacity = if opacity.is_nan() {
            0.0
        } else {
            opacity.clamp(0.0, 1.0)
        };
        (color.truncate(), opacity)
    }
}

/// Reads a `color` array of any Color element type as linear RGBA (missing components: 0 for
/// green and blue, 1 for alpha; the second component of red–alpha colours is alpha).
fn read_colors(store: &ArrayStore) -> Option<Vec<Vec4>> {
    let mut colors = read_values(store)?;
    if store.element_type == ANARI_UFIXED8_RA_SRGB {
        for color in &mut colors {
            (color.y, color.w) = (0.0, color.y);
        }
    }
    Some(colors)
}

/// Builds the transfer function from the committed parameters; reports and returns `None` when
/// the volume cannot be rendered.
pub fn commit(device: &Device, object: &Object) -> Option<TransferFunction> {
    if object.subtype != TRANSFER_FUNCTION1D.subtype {
        return None;
    }
    let params = object.committed();
    let what = "anariCommitParameters: volume 'transferFunction1D'";
    let fail = |text: String| {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!("{what} {text}; the volume is not rendered"),
        );
        None
    };

    let value_range = match params.get_raw("valueRange") {
        Some((ANARI_FLOAT32_BOX1, b)) => (
            f32::from_ne_bytes(b[0..4].try_into().unwrap()),
            f32::from_ne_bytes(b[4..8].try_into().unwrap()),
        ),
        Some((ANARI_FLOAT64_BOX1, b)) => (
            f64::from_ne_bytes(b[0..8].try_into().unwrap()) as f32,
            f64::from_ne_bytes(b[8..16].try_into().unwrap()) as f32,
        ),
        _ => (0.0, 1.0),
    };
    let (lo, hi) = value_range;
    if !lo.is_finite() || !hi.is_finite() {
        return fail(format!("parameter 'valueRange' [{lo}, {hi}] is not finite"));
    }
    if lo > hi {
        device.warning(
            Some(object),
            format!(
                "{what} parameter 'valueRange' [{lo}, {hi}] is reversed: rendered as a reversed \
                 mapping, value {lo} at the first table entry and {hi} at the last"
            ),
        );
    }

    let colors = match params.get("color") {
        None => vec![Vec4::ONE],
        Some(ParamValue::Object { object: array, .. }) => {
            let Some(colors) = array.array.as_ref().and_then(read_colors) else {
                return fail(format!(
                    "parameter 'color': the {} holds no readable colours",
                    array.describe()
                ));
            };
            colors
        }
        Some(_) => match (params.get_vec4("color"), params.get_vec3("color")) {
            (Some(c), _) => vec![c],
            (None, Some(c)) => vec![c.extend(1.0)],
            _ => vec![Vec4::ONE],
        },
    };
    if colors.is_empty() {
        return fail("parameter 'color' is an empty array".into());
    }

    let opacities = match params.get("opacity") {
        None => vec![1.0],
        Some(ParamValue::Object { object: array, .. }) => {
            let Some(opacities) = array.array.as_ref().and_then(|a| a.read_f32()) else {
                return fail(format!(
                    "parameter 'opacity': the {} does not hold ANARI_FLOAT32 values",
                    array.describe()
                ));
            };
            opacities
        }
        Some(_) => vec![params.get_f32("opacity").unwrap_or(1.0)],
    };
    if opacities.is_empty() {
        return fail("parameter 'opacity' is an empty array".into());
    }

    let unit_distance = params.get_f32("unitDistance").unwrap_or(1.0);
    if !unit_distance.is_finite() || unit_distance <= 0.0 {
        return fail(format!(
            "parameter 'unitDistance' {unit_distance} must be finite and positive"
        ));
    }

    // A missing 'value' is already reported as a missing required parameter.
    if let Some(field) = params.get_object("value")
        && Field::of(field).is_none()
    {
        device.warning(
            Some(object),
            format!(
                "{what} parameter 'value': the {} is not a usable committed field; the volume \
                 renders nothing until one is committed",
                field.describe()
            ),
        );
    }

    TransferFunction::new(
        params.get_u32("id").unwrap_or(u32::MAX),
        value_range,
        colors,
        opacities,
        unit_distance,
    )
}

/// A volume as a frame renders it: transfer function, field and placement.
#[derive(Debug, Clone)]
pub struct PlacedVolume {
    pub transfer: Arc<TransferFunction>,
    pub field: Field,
    pub object_to_world: Affine3A,
    pub world_to_object: Affine3A,
    /// channel.instanceId value.
    pub instance_id: u32,
    /// Per macrocell of the field: whether the transfer function makes any of its values
    /// visible.
    pub occupied: Arc<[bool]>,
    /// Per macrocell: the largest extinction (optical depth per world unit) its values may
    /// have; 0 where empty, infinite where opaque.
    pub extinction_bounds: Arc<[f32]>,
}

impl PlacedVolume {
    /// `object_to_world` must be invertible.
    pub fn new(
        transfer: Arc<TransferFunction>,
        field: impl Into<Field>,
        object_to_world: Affine3A,
        instance_id: u32,
    ) -> PlacedVolume {
        let field: Field = field.into();
        let ranges = field.macrocells().ranges();
        let occupied = ranges
            .iter()
            .map(|&range| transfer.may_be_visible(range))
            .collect();
        let extinction_bounds = ranges
            .iter()
            .map(|&range| -(-transfer.max_opacity(range)).ln_1p() / transfer.unit_distance)
            .collect();
        PlacedVolume {
            transfer,
            field,
            object_to_world,
            world_to_object: object_to_world.inverse(),
            instance_id,
            occupied,
            extinction_bounds,
        }
    }

    /// World-space box around the field's transformed box.
    pub fn world_bounds(&self) -> (Vec3, Vec3) {
        let (lo, hi) = self.field.bounds();
        let mut min = Vec3::splat(f32::INFINITY);
        let mut max = Vec3::splat(f32::NEG_INFINITY);
        for corner in 0..8 {
            let p = Vec3::new(
                if corner & 1 == 0 { lo.x } else { hi.x },
                if corner & 2 == 0 { lo.y } else { hi.y },
                if corner & 4 == 0 { lo.z } else { hi.z },
            );
            let w = self.object_to_world.transform_point3(p);
            min = min.min(w);
            max = max.max(w);
        }
        (min, max)
    }
}

/// Where a ray first meets a volume that absorbs anything.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeHit {
    pub t: f32,
    pub object_id: u32,
    pub instance_id: u32,
    /// Transfer-function colour there.
    pub color: Vec3,
}

/// What the volumes along a ray segment do to the light travelling back along it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeIntegral {
    /// Light the volumes emit towards the ray origin (already attenuated by what lies between).
    pub color: Vec3,
    /// Fraction of the light from behind the segment that gets through (0 once marching stopped
    /// early).
    pub transmittance: f32,
    pub first: Option<VolumeHit>,
}

impl Default for VolumeIntegral {
    /// Nothing crossed yet: no light, everything gets through.
    fn default() -> VolumeIntegral {
        VolumeIntegral {
            color: Vec3::ZERO,
            transmittance: 1.0,
            first: None,
        }
    }
}

impl VolumeIntegral {
    /// This segment in front of `behind` (linear RGBA, alpha as coverage).
    pub fn over(&self, behind: Vec4) -> Vec4 {
        let t = self.transmittance;
        (self.color + behind.truncate() * t).extend(1.0 - t + behind.w * t)
    }

    /// Adds one marching step that emits `emitted` per unit of opacity; false once the segment
    /// has become opaque (the transmittance is then 0).
    pub fn absorb(&mut self, step: &MarchStep, emitted: Vec3) -> bool {
        if self.first.is_none() {
            self.first = Some(VolumeHit {
                t: step.t,
                object_id: step.strongest.transfer.id,
                instance_id: step.strongest.instance_id,
                color: step.strongest_color,
            });
        }
        let step_transmittance = step.transmittance();
        self.color += emitted * (self.transmittance * (1.0 - step_transmittance));
        self.transmittance *= step_transmittance;
        if self.transmittance < OPAQUE_TRANSMITTANCE {
            self.transmittance = 0.0;
            return false;
        }
        true
    }
}

/// One marching sample where some volume is not transparent.
pub struct MarchStep<'a> {
    /// Where the sample was taken (ray parameter).
    pub t: f32,
    /// The stretch of the ray the sample stands for: from `begin`, `dt` long (ray parameter).
    pub begin: f32,
    pub dt: f32,
    /// Optical depth over the stretch; infinite where a volume is opaque.
    pub optical_depth: f32,
    /// The volumes' colours weighted by their share of the optical depth (the opaque ones'
    /// mean where any is opaque).
    pub color: Vec3,
    /// The volume with the largest share, and its colour (for the id channels).
    pub strongest: &'a PlacedVolume,
    pub strongest_color: Vec3,
}

impl MarchStep<'_> {
    /// Fraction of the light that crosses the step.
    #[inline]
    pub fn transmittance(&self) -> f32 {
        if self.optical_depth.is_finite() {
            (-self.optical_depth).exp()
        } else {
            0.0
        }
    }
}

/// One volume's stretch of the ray, in that volume's object space.
struct Span {
    volume: usize,
    t0: f32,
    t1: f32,
    origin: Vec3,
    direction: Vec3,
    /// Sample spacing in ray parameter units.
    step: f32,
    /// Stretches crossing macrocells that are not empty (all of [t0, t1] without skipping),
    /// each with its step multiple.
    occupied: Vec<(f32, f32, u32)>,
}

/// Ray parameters where `origin + t × direction` is inside the box, if any.
fn slab(lo: Vec3, hi: Vec3, origin: Vec3, direction: Vec3) -> Option<(f32, f32)> {
    let mut t0 = f32::NEG_INFINITY;
    let mut t1 = f32::INFINITY;
    for axis in 0..3 {
        let (o, d) = (origin[axis], direction[axis]);
        if d == 0.0 {
            if o < lo[axis] || o > hi[axis] {
                return None;
            }
            continue;
        }
        let (a, b) = ((lo[axis] - o) / d, (hi[axis] - o) / d);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1).then_some((t0, t1))
}

/// The volumes present at `t` classified and combined over a step of `length` world units:
/// `None` where all are transparent.
fn sample_at<'a>(
    volumes: &'a [PlacedVolume],
    active: &[&Span],
    t: f32,
    begin: f32,
    dt: f32,
    length: f32,
) -> Option<MarchStep<'a>> {
    // Optical depth of every volume present; colours weighted by their share of it.
    let mut optical_depth = 0.0f32;
    let mut weighted = Vec3::ZERO;
    let mut opaque = (0u32, Vec3::ZERO);
    let mut strongest: Option<(f32, &PlacedVolume, Vec3)> = None;
    for span in active {
        let volume = &volumes[span.volume];
        let value = volume.field.sample(span.origin + span.direction * t);
        let (color, opacity) = volume.transfer.classify(value);
        if opacity <= 0.0 {
            continue;
        }
        let depth = if opacity >= 1.0 {
            opaque = (opaque.0 + 1, opaque.1 + color);
            f32::INFINITY
        } else {
            -(-opacity).ln_1p() * length / volume.transfer.unit_distance
        };
        if depth <= 0.0 {
            continue;
        }
        optical_depth += depth;
        if depth.is_finite() {
            weighted += color * depth;
        }
        if strongest.is_none_or(|(d, _, _)| depth > d) {
            strongest = Some((depth, volume, color));
        }
    }
    let (_, volume, strongest_color) = strongest?;
    let color = if opaque.0 > 0 {
        opaque.1 / opaque.0 as f32
    } else {
        weighted / optical_depth
    };
    Some(MarchStep {
        t,
        begin,
        dt,
        optical_depth,
        color,
        strongest: volume,
        strongest_color,
    })
}

/// Marches the volumes along `origin + t × direction` for `t` in [`t_start`, `t_end`], front to
/// back, calling `visit` for every sample where something is not transparent until it returns
/// false. Between consecutive volume entry and exit points base steps are evenly spaced, one
/// per stretch of the finest volume's step; each sample stands for a whole number of base
/// steps (one unless `stepping` is adaptive) and is taken `jitter` (in [0, 1)) of the way into
/// its stretch. See [`Stepping`] for what is skipped. `None` when no volume overlaps the
/// segment; otherwise the number of field samples taken.
#[allow(clippy::too_many_arguments)]
pub fn march<'a>(
    volumes: &'a [PlacedVolume],
    origin: Vec3,
    direction: Vec3,
    t_start: f32,
    t_end: f32,
    jitter: f32,
    stepping: Stepping,
    mut visit: impl FnMut(&MarchStep<'a>) -> bool,
) -> Option<u32> {
    if volumes.is_empty() || t_start.is_nan() || t_end.is_nan() || t_start >= t_end {
        return None;
    }
    let world_per_t = direction.length();
    let mut spans: Vec<Span> = Vec::new();
    for (index, volume) in volumes.iter().enumerate() {
        let o = volume.world_to_object.transform_point3(origin);
        let d = volume.world_to_object.transform_vector3(direction);
        if !o.is_finite() || !d.is_finite() || d == Vec3::ZERO {
            continue;
        }
        let (lo, hi) = volume.field.bounds();
        let Some((t0, t1)) = slab(lo, hi, o, d) else {
            continue;
        };
        let (t0, t1) = (t0.max(t_start), t1.min(t_end));
        if t0 < t1 {
            let step = volume.field.step() / d.length();
            let mut occupied = Vec::new();
            let cells = volume.field.macrocells();
            match stepping {
                Stepping::Fixed => occupied.push((t0, t1, 1)),
                Stepping::SkipEmpty => cells.classified_spans(
                    |block| u32::from(volume.occupied[block]),
                    o,
                    d,
                    (t0, t1),
                    &mut occupied,
                ),
                Stepping::Adaptive => {
                    // Optical depth of one base step at unit extinction.
                    let base = step * world_per_t;
                    let multiple = |block: usize| {
                        if !volume.occupied[block] {
                            return 0;
                        }
                        let depth = volume.extinction_bounds[block] * base;
                        // NaN and infinity (opaque) fall to one base step.
                        (ADAPTIVE_OPTICAL_DEPTH / depth).clamp(1.0, MAX_STEP_MULTIPLE as f32) as u32
                    };
                    cells.classified_spans(multiple, o, d, (t0, t1), &mut occupied);
                }
            }
            spans.push(Span {
                volume: index,
                origin: o,
                direction: d,
                t0,
                t1,
                step,
                occupied,
            });
        }
    }
    if spans.is_empty() {
        return None;
    }
    // Between consecutive entry/exit points the set of volumes present is fixed.
    let mut cuts: Vec<f32> = spans.iter().flat_map(|s| [s.t0, s.t1]).collect();
    cuts.sort_by(f32::total_cmp);
    cuts.dedup();
    let mut samples = 0u32;
    let mut active: Vec<&Span> = Vec::with_capacity(spans.len());
    let mut stretches: Vec<(f32, f32, u32)> = Vec::new();
    for window in cuts.windows(2) {
        let (a, b) = (window[0], window[1]);
        active.clear();
        active.extend(spans.iter().filter(|s| s.t0 <= a && s.t1 >= b));
        let Some(step) = active.iter().map(|s| s.step).reduce(f32::min) else {
            continue;
        };
        // Equal steps that end exactly at b: a constant field gives the exact transmittance.
        let steps = ((b - a) / step).ceil().clamp(1.0, MAX_STEPS) as u32;
        let dt = (b - a) / steps as f32;
        stretches.clear();
        for span in &active {
            stretches.extend(
                span.occupied
                    .iter()
                    .filter(|(lo, hi, _)| *hi >= a && *lo <= b),
            );
        }
        stretches.sort_by(|x, y| x.0.total_cmp(&y.0));
        // Where volumes overlap, one volume's long steps could pass over another's detail.
        let overlapping = active.len() > 1;
        // Base steps in each stretch, widened by one on each side against rounding, taken
        // `multiple` at a time (fewer at the stretch's end).
        let mut next = 0u32;
        for &(lo, hi, multiple) in &stretches {
            let multiple = if overlapping { 1 } else { multiple.max(1) };
            let first = (((lo - a) / dt - jitter).floor().max(0.0) as u32).max(next);
            let end = ((((hi - a) / dt - jitter).ceil() + 1.0).max(0.0) as u32).min(steps);
            let mut i = first;
            while i < end {
                let count = multiple.min(end - i) as f32;
                let begin = a + dt * i as f32;
                let t = a + dt * (i as f32 + jitter * count);
                let length = dt * count;
                samples += 1;
                if let Some(sample) =
                    sample_at(volumes, &active, t, begin, length, length * world_per_t)
                    && !visit(&sample)
                {
                    return Some(samples);
                }
                i += multiple;
            }
            next = next.max(end);
        }
    }
    Some(samples)
}

/// Emission–absorption along `origin + t × direction` for `t` in [`t_start`, `t_end`]: every
/// volume emits its colour in proportion to its opacity. `None` when no volume overlaps that
/// stretch (nothing changes the light).
pub fn integrate(
    volumes: &[PlacedVolume],
    origin: Vec3,
    direction: Vec3,
    t_start: f32,
    t_end: f32,
) -> Option<VolumeIntegral> {
    let mut result = VolumeIntegral::default();
    march(
        volumes,
        origin,
        direction,
        t_start,
        t_end,
        0.0,
        Stepping::DEFAULT,
        |step| result.absorb(step, step.color),
    )?;
    Some(result)
}

/// Fraction of light that crosses the volumes from `origin + t_start × direction` to
/// `origin + t_end × direction` (0 once below the opaque threshold), samples `jitter` into their
/// stretch, placed by `stepping` (see [`march`]), and the number of field samples taken.
pub fn transmittance(
    volumes: &[PlacedVolume],
    origin: Vec3,
    direction: Vec3,
    (t_start, t_end): (f32, f32),
    jitter: f32,
    stepping: Stepping,
) -> (f32, u32) {
    let mut through = 1.0f32;
    let samples = march(
        volumes,
        origin,
        direction,
        t_start,
        t_end,
        jitter,
        stepping,
        |step| {
            through *= step.transmittance();
            if through < OPAQUE_TRANSMITTANCE {
                through = 0.0;
            }
            through > 0.0
        },
    );
    (through, samples.unwrap_or(0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spatial_field::StructuredRegularField;

    fn constant_box(value: f32, opacity: f32, unit_distance: f32, id: u32) -> PlacedVolume {
        // Unit cube [0,1]³ with every vertex at `value`.
        let field = StructuredRegularField::from_floats(
            [2, 2, 2],
            vec![value; 8],
            Vec3::ZERO,
            Vec3::ONE,
            false,
        )
        .unwrap();
        let transfer = TransferFunction::new(
            id,
            (0.0, 1.0),
            vec![Vec4::new(1.0, 0.5, 0.25, 1.0)],
            vec![opacity],
            unit_distance,
        )
        .unwrap();
        PlacedVolume::new(Arc::new(transfer), Arc::new(field), Affine3A::IDENTITY, 7)
    }

    #[test]
    fn a_constant_box_transmits_the_analytic_fraction() {
        let volume = constant_box(0.5, 0.5, 0.25, 3);
        let result = integrate(
            &[volume],
            Vec3::new(0.5, 0.5, 5.0),
            Vec3::NEG_Z,
            0.0,
            f32::INFINITY,
        )
        .unwrap();
        // Path length 1 = 4 unit distances: 0.5⁴ of the light gets through.
        let expected = 0.5f32.powi(4);
        assert!((result.transmittance - expected).abs() < 1e-5);
        let emitted = Vec3::new(1.0, 0.5, 0.25) * (1.0 - expected);
        assert!((result.color - emitted).abs().max_element() < 1e-5);
        let first = result.first.unwrap();
        assert!((first.t - 4.0).abs() < 1e-5);
        assert_eq!((first.object_id, first.instance_id), (3, 7));
    }

    #[test]
    fn shadow_rays_see_the_analytic_transmittance_wherever_samples_fall() {
        // Opacity 0.3 per unit distance 0.4: σ = −ln(0.7)/0.4. A ray entering at x = 0 at
        // 30° from the axis crosses 1/cos 30° of the box before leaving through x = 1.
        let volume = constant_box(0.5, 0.3, 0.4, 0);
        let sigma = -(0.7f32.ln()) / 0.4;
        let direction = Vec3::new(30f32.to_radians().cos(), 0.0, 30f32.to_radians().sin());
        let origin = Vec3::new(0.0, 0.5, 0.1) - direction;
        let path = 1.0 / 30f32.to_radians().cos();
        for jitter in [0.0, 0.3, 0.77, 0.999] {
            for stepping in [Stepping::Adaptive, Stepping::SkipEmpty, Stepping::Fixed] {
                let volumes = std::slice::from_ref(&volume);
                let (through, samples) =
                    transmittance(volumes, origin, direction, (0.0, 100.0), jitter, stepping);
                let expected = (-sigma * path).exp();
                assert!((through - expected).abs() < 1e-5, "{through} vs {expected}");
                assert!(samples >= 1);
            }
        }
        // Stopping halfway through the box.
        let half = 1.0 + 0.5 * path;
        let (through, _) = transmittance(
            &[volume],
            origin,
            direction,
            (0.0, half),
            0.5,
            Stepping::DEFAULT,
        );
        assert!((through - (-sigma * path * 0.5).exp()).abs() < 1e-5);
    }

    #[test]
    fn overlapping_volumes_absorb_together() {
        // Two identical boxes in the same place absorb like one with twice the optical depth.
        let a = constant_box(0.5, 0.5, 1.0, 1);
        let b = constant_box(0.5, 0.5, 1.0, 2);
        let result = integrate(&[a, b], Vec3::new(0.5, 0.5, 5.0), Vec3::NEG_Z, 0.0, 100.0).unwrap();
        assert!((result.transmittance - 0.25).abs() < 1e-5);
        assert!((result.color.x - 0.75).abs() < 1e-5);
    }

    #[test]
    fn segments_clip_the_march_and_misses_report_nothing() {
        let volume = constant_box(0.5, 0.5, 1.0, 0);
        let half = integrate(
            std::slice::from_ref(&volume),
            Vec3::new(0.5, 0.5, 5.0),
            Vec3::NEG_Z,
            0.0,
            4.5,
        )
        .unwrap();
        assert!((half.transmittance - 0.5f32.sqrt()).abs() < 1e-5);
        let miss = integrate(&[volume], Vec3::new(3.0, 0.5, 5.0), Vec3::NEG_Z, 0.0, 100.0);
        assert!(miss.is_none());
    }

    #[test]
    fn tables_interpolate_over_the_value_range_and_alpha_scales_opacity() {
        let transfer = TransferFunction::new(
            0,
            (2.0, 4.0),
            vec![Vec4::new(0.0, 0.0, 0.0, 0.5), Vec4::new(1.0, 1.0, 1.0, 0.5)],
            vec![0.0, 0.5, 1.0],
            1.0,
        )
        .unwrap();
        let (c, o) = transfer.classify(3.0);
        assert!((c.x - 0.5).abs() < 1e-6 && (o - 0.25).abs() < 1e-6);
        assert_eq!(transfer.classify(-10.0), (Vec3::ZERO, 0.0));
        assert_eq!(transfer.classify(10.0), (Vec3::ONE, 0.5));
        assert_eq!(transfer.classify(f32::NAN), (Vec3::ZERO, 0.0));
        // A reversed range reverses the mapping.
        let reversed = TransferFunction::new(
            0,
            (4.0, 2.0),
            vec![Vec4::new(0.0, 0.0, 0.0, 0.5), Vec4::new(1.0, 1.0, 1.0, 0.5)],
            vec![0.0, 0.5, 1.0],
            1.0,
        )
        .unwrap();
        let (c, o) = reversed.classify(2.5);
        assert!(
            (c.x - 0.75).abs() < 1e-6 && (o - 0.375).abs() < 1e-6,
            "{c} {o}"
        );
        assert_eq!(reversed.classify(10.0), (Vec3::ZERO, 0.0));
        assert_eq!(reversed.classify(-10.0), (Vec3::ONE, 0.5));
    }
}
