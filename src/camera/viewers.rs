//! Several tracked viewers sharing the screens of a CAVE (Schulze et al., "Democratizing
//! Rendering for Multiple Viewers in Surround VR Systems"): each point of a screen is seen from
//! a camera position blended between the viewers' heads, weighted by how directly each viewer
//! looks at that point.
//!
//! Viewer `i` has head `H_i`, gaze `D_i` and right vector `R_i`. For a screen point `P`, its
//! angle `a_i` is the angle between `D_i` and `P − H_i`; with the cutoff angle `c` the weights
//! are
//! - linear: `1 − a/c` for `a < c`, else 0;
//! - cosine: `cos(a/c)` for `a < c·π/2`, else 0 (the cosine falls to 0 exactly there, so the
//!   weight stays continuous; `c` is then the angle where the weight is cos 1 ≈ 0.54);
//! - gaussian: `erfc(a / (σ√2))` with `σ = c/3`, twice the upper tail of a normal distribution:
//!   1 at `a = 0`, 0.0027 at `a = c`, and never 0 (weights are normalised in log space, so the
//!   nearest viewers keep their share however far every viewer looks away).
//!
//! Weights are normalised to sum to 1 and the camera is `C(P) = Σ ŵ_i H_i`; where every weight
//! is 0 it is the mean of all heads. Zones use cone membership instead: inside exactly one
//! viewer's cone (`a_i < c`) that viewer's head, inside several the mean of their heads,
//! inside none the mean of all heads. In stereo the eyes sit at `C(P) ± (ipd/2)·R(P)` with
//! `R(P)` the normalised weighted sum of the right vectors.
//!
//! Weights and the blend are evaluated in f32, lane by lane over arrays of screen points (four
//! for single rays, a whole 8×8 block for the frame's blocks) so that the compiler makes them
//! SIMD: the same operations in every lane and on every instruction-set path, so the same bits
//! whichever points a lane comes with. A point seen by one viewer alone gets exactly that
//! viewer's head and right vector.

use glam::{DVec2, DVec3, Vec3};

use super::CameraError;
use super::offaxis::ScreenFrame;
use crate::isa::Isa;

/// Most viewers one camera blends (per-pixel work grows with their number).
pub const MAX_VIEWERS: usize = 64;

/// Default `viewerCutoffAngle`, radians.
pub const DEFAULT_CUTOFF_ANGLE: f32 = std::f32::consts::FRAC_PI_4;

/// Default `viewerTiles`.
pub const DEFAULT_TILES: [u32; 2] = [8, 8];

/// `viewerMode`: which screen point's weights choose a pixel's camera.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ViewerMode {
    /// The pixel centre's own point.
    #[default]
    PerPixel,
    /// The centre of the pixel's tile in a regular grid over the screen.
    Tiles,
    /// Cone membership of the pixel centre's point.
    Zones,
}

impl ViewerMode {
    pub const VALUES: [&'static str; 3] = ["perPixel", "tiles", "zones"];

    pub fn parse(value: &str) -> Option<ViewerMode> {
        match value {
            "perPixel" => Some(ViewerMode::PerPixel),
            "tiles" => Some(ViewerMode::Tiles),
            "zones" => Some(ViewerMode::Zones),
            _ => None,
        }
    }
}

/// `viewerWeighting`: how a viewer's weight falls off with its angle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ViewerWeighting {
    #[default]
    Linear,
    Cosine,
    Gaussian,
}

impl ViewerWeighting {
    pub const VALUES: [&'static str; 3] = ["linear", "cosine", "gaussian"];

    pub fn parse(value: &str) -> Option<ViewerWeighting> {
        match value {
            "linear" => Some(ViewerWeighting::Linear),
            "cosine" => Some(ViewerWeighting::Cosine),
            "gaussian" => Some(ViewerWeighting::Gaussian),
            _ => None,
        }
    }
}

/// The viewers as the application set them (one element per viewer).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewerDesc {
    pub positions: Vec<Vec3>,
    pub directions: Vec<Vec3>,
    /// Unset: every viewer's right vector is the screen's X axis.
    pub rights: Option<Vec<Vec3>>,
    pub mode: ViewerMode,
    pub weighting: ViewerWeighting,
    pub cutoff_angle: f32,
    pub tiles: [u32; 2],
}

impl ViewerDesc {
    /// Viewers at `positions` looking along `directions`, with the default mode and weighting.
    pub fn new(positions: Vec<Vec3>, directions: Vec<Vec3>) -> ViewerDesc {
        ViewerDesc {
            positions,
            directions,
            rights: None,
            mode: ViewerMode::default(),
            weighting: ViewerWeighting::default(),
            cutoff_angle: DEFAULT_CUTOFF_ANGLE,
            tiles: DEFAULT_TILES,
        }
    }
}

/// One viewer in f32, as the blend reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ViewerF32 {
    head: [f32; 3],
    /// Unit length.
    gaze: [f32; 3],
    /// Unit length.
    right: [f32; 3],
}

/// A camera position and its right vector.
type CameraAt = (DVec3, DVec3);

/// Camera positions and right vectors of `N` screen points, x, y and z by lane.
#[derive(Clone, Debug)]
pub(crate) struct CameraLanes<const N: usize> {
    pub head: [[f64; N]; 3],
    pub right: [[f64; N]; 3],
}

impl<const N: usize> Default for CameraLanes<N> {
    fn default() -> CameraLanes<N> {
        CameraLanes {
            head: [[0.0; N]; 3],
            right: [[0.0; N]; 3],
        }
    }
}

impl<const N: usize> CameraLanes<N> {
    /// Lane `l`'s camera position.
    #[inline(always)]
    pub fn head_at(&self, l: usize) -> DVec3 {
        DVec3::new(self.head[0][l], self.head[1][l], self.head[2][l])
    }

    /// Lane `l`'s right vector.
    #[inline(always)]
    pub fn right_at(&self, l: usize) -> DVec3 {
        DVec3::new(self.right[0][l], self.right[1][l], self.right[2][l])
    }

    /// Lanes `l` where `take(l)` holds get `head` and `right` (every lane rewritten, with a
    /// select: no branch per lane).
    #[inline(always)]
    fn set_where(&mut self, take: impl Fn(usize) -> bool, head: DVec3, right: DVec3) {
        for axis in 0..3 {
            for l in 0..N {
                let taken = take(l);
                let (h, r) = (self.head[axis][l], self.right[axis][l]);
                self.head[axis][l] = if taken { head[axis] } else { h };
                self.right[axis][l] = if taken { right[axis] } else { r };
            }
        }
    }

    #[inline(always)]
    fn set(&mut self, l: usize, head: DVec3, right: DVec3) {
        for axis in 0..3 {
            self.head[axis][l] = head[axis];
            self.right[axis][l] = right[axis];
        }
    }
}

/// Validated viewers, ready to give any screen point its camera.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewerSet {
    heads: Vec<DVec3>,
    rights: Vec<DVec3>,
    /// Per viewer, in f32.
    viewers_f32: Vec<ViewerF32>,
    mean_head: DVec3,
    /// The normalised sum of the right vectors, for points no viewer has a say on (the
    /// screen's X axis where they cancel).
    mean_right: DVec3,
    mode: ViewerMode,
    weighting: ViewerWeighting,
    inv_cutoff: f32,
    /// Cosine of the angle beyond which the weight (or zone membership) is 0.
    cos_reach: f32,
    /// `1 / (σ√2)` for the gaussian fall-off.
    gaussian_scale: f32,
    tiles: [u32; 2],
    /// Per tile (row by row), its camera position and right vector, for grids up to
    /// [`MAX_PRECOMPUTED_TILES`] tiles; larger ones are computed pixel by pixel.
    tile_cameras: Vec<(DVec3, DVec3)>,
    screen: ScreenFrame,
}

/// Largest tile grid whose cameras are computed once at commit.
const MAX_PRECOMPUTED_TILES: u32 = 16384;

impl ViewerSet {
    /// Validates the viewers against `screen`; `eye_offset` is the largest distance of an eye
    /// from its head (half the interpupillary distance in stereo, else 0): every eye must stay
    /// in front of the screen.
    pub(crate) fn new(
        desc: &ViewerDesc,
        screen: ScreenFrame,
        eye_offset: f64,
    ) -> Result<ViewerSet, CameraError> {
        let count = desc.positions.len();
        if count == 0 {
            return Err(CameraError::new(
                "viewer.position",
                "must hold at least one viewer",
            ));
        }
        if count > MAX_VIEWERS {
            return Err(CameraError::new(
                "viewer.position",
                format!("holds {count} viewers, at most {MAX_VIEWERS} are supported"),
            ));
        }
        let same_length = |name: &str, length: usize| {
            if length == count {
                Ok(())
            } else {
                Err(CameraError::new(
                    name,
                    format!("has {length} elements but viewer.position has {count}"),
                ))
            }
        };
        same_length("viewer.direction", desc.directions.len())?;
        if let Some(rights) = &desc.rights {
            same_length("viewer.right", rights.len())?;
        }
        let cutoff = desc.cutoff_angle;
        if !(cutoff.is_finite() && cutoff > 0.0 && cutoff <= std::f32::consts::PI) {
            return Err(CameraError::new(
                "viewerCutoffAngle",
                format!("must be in (0, π] radians, got {cutoff}"),
            ));
        }
        if desc.tiles.contains(&0) {
            return Err(CameraError::new(
                "viewerTiles",
                format!("must be at least 1×1, got {:?}", desc.tiles),
            ));
        }
        let element_error = |name: &str, index: usize, message: String| {
            CameraError::new(name, format!("viewer {index}: {message}"))
        };
        let mut heads = Vec::with_capacity(count);
        let mut gazes = Vec::with_capacity(count);
        let mut rights = Vec::with_capacity(count);
        for index in 0..count {
            let head = desc.positions[index];
            if !head.is_finite() {
                return Err(element_error(
                    "viewer.position",
                    index,
                    format!("must be finite, got {head}"),
                ));
            }
            let head = head.as_dvec3();
            let distance = screen.signed_distance(head);
            if screen.eye_distance(head).is_err() || distance <= eye_offset {
                return Err(element_error(
                    "viewer.position",
                    index,
                    format!(
                        "the head at {head} is {distance} m from the screen plane; heads must be \
                         clearly in front of it{}",
                        if eye_offset > 0.0 {
                            format!(
                                " and farther than half the interpupillary distance ({eye_offset} m)"
                            )
                        } else {
                            String::new()
                        }
                    ),
                ));
            }
            let unit = |name: &str, v: Vec3| {
                let v = v.as_dvec3();
                let length = v.length();
                if v.is_finite() && length > 0.0 && length.is_finite() {
                    Ok(v / length)
                } else {
                    Err(element_error(
                        name,
                        index,
                        format!("must be a finite, non-zero vector, got {v}"),
                    ))
                }
            };
            gazes.push(unit("viewer.direction", desc.directions[index])?);
            rights.push(match &desc.rights {
                Some(values) => unit("viewer.right", values[index])?,
                None => screen.x,
            });
            heads.push(head);
        }
        let single = |v: &DVec3| v.as_vec3().to_array();
        let viewers_f32 = heads
            .iter()
            .zip(&gazes)
            .zip(&rights)
            .map(|((head, gaze), right)| ViewerF32 {
                head: single(head),
                gaze: single(gaze),
                right: single(right),
            })
            .collect();
        let mean_head = heads.iter().sum::<DVec3>() / count as f64;
        let mean_right = match rights[..] {
            [only] => only,
            _ => rights
                .iter()
                .sum::<DVec3>()
                .try_normalize()
                .unwrap_or(screen.x),
        };
        let reach = match desc.weighting {
            ViewerWeighting::Cosine if desc.mode != ViewerMode::Zones => {
                cutoff * std::f32::consts::FRAC_PI_2
            }
            _ => cutoff,
        };
        let mut set = ViewerSet {
            heads,
            rights,
            viewers_f32,
            mean_head,
            mean_right,
            mode: desc.mode,
            weighting: desc.weighting,
            inv_cutoff: 1.0 / cutoff,
            cos_reach: if reach >= std::f32::consts::PI {
                -2.0
            } else {
                reach.cos()
            },
            gaussian_scale: 3.0 / (cutoff * std::f32::consts::SQRT_2),
            tiles: desc.tiles,
            tile_cameras: Vec::new(),
            screen,
        };
        let [columns, rows] = desc.tiles;
        if desc.mode == ViewerMode::Tiles && columns.saturating_mul(rows) <= MAX_PRECOMPUTED_TILES {
            set.tile_cameras = (0..rows)
                .flat_map(|row| (0..columns).map(move |column| (column, row)))
                .map(|(column, row)| set.camera_at_point(set.tile_centre(column, row), true))
                .collect();
        }
        Ok(set)
    }

    /// The normalised weights of the viewers at screen point `point` (`weights[i]` for viewer
    /// `i`), as the mode defines them: perPixel and tiles by the weighting function, zones
    /// `1/n` for the `n` viewers whose cone holds the point. `false` (weights all 0) where no
    /// viewer has a say, and the camera is the mean of all heads.
    pub fn weights_at(&self, point: DVec3, weights: &mut [f32; MAX_VIEWERS]) -> bool {
        let mut lanes = [[0.0; 1]; MAX_VIEWERS];
        let (any, _) = self.weights_of(&[point], &mut lanes, true);
        for (weight, lane) in weights.iter_mut().zip(&lanes) {
            *weight = lane[0];
        }
        any & 1 != 0
    }

    /// The normalised weights at `N` screen points at once: `weights[i]` holds viewer `i`'s
    /// weight at each point (lane = point). Returns the mask of lanes where some viewer has a
    /// say (the others' weights are 0) and the mask of viewers with a weight above 0 at some
    /// point (the others' weights are 0 at every point). A point in one viewer's cone alone
    /// (and, but for the gaussian fall-off, outside every other one) is that viewer's,
    /// whatever the fall-off: its weight is exactly 1, so only points in several cones pay for
    /// angles. Every lane gets the same result whatever the other lanes hold: only plain IEEE
    /// operations, lane by lane (no fused multiply-adds, which the compiler never makes on its
    /// own). With `skip_absent`, viewers whose cone holds none of the points skip the angles (and
    /// the blend): their weights stay 0, which changes no other bit.
    #[inline(always)]
    fn weights_of<const N: usize>(
        &self,
        points: &[DVec3; N],
        weights: &mut [[f32; N]],
        skip_absent: bool,
    ) -> (u64, u64) {
        // One bit per lane in the result.
        const { assert!(N <= 64) };
        let lane = |axis: usize| -> [f32; N] { std::array::from_fn(|l| points[l][axis] as f32) };
        let p = [lane(0), lane(1), lane(2)];
        let weights = &mut weights[..self.heads.len()];
        let gaussian =
            self.weighting == ViewerWeighting::Gaussian && self.mode != ViewerMode::Zones;
        if gaussian {
            // Log weights first, exponentiated relative to each point's largest.
            let mut log_max = [f32::NEG_INFINITY; N];
            for (weight, viewer) in weights.iter_mut().zip(&self.viewers_f32) {
                let a = angles(viewer, &p);
                for l in 0..N {
                    weight[l] = ln_erfc(a[l] * self.gaussian_scale);
                    log_max[l] = max(log_max[l], weight[l]);
                }
            }
            let mut total = [0.0; N];
            for weight in weights.iter_mut() {
                for l in 0..N {
                    weight[l] = (weight[l] - log_max[l]).exp();
                    total[l] += weight[l];
                }
            }
            for weight in weights.iter_mut() {
                for l in 0..N {
                    weight[l] /= total[l];
                }
            }
            return (
                lanes_where(N, |_| true),
                lanes_where(weights.len(), |_| true),
            );
        }
        // Cone membership without a square root: cos a > cos c, squared with its sign.
        let reach = self.cos_reach;
        let reach_squared = reach * reach;
        let mut members = [0.0f32; N];
        // Viewers whose cone holds some point.
        let mut present = 0u64;
        for (index, (weight, viewer)) in weights.iter_mut().zip(&self.viewers_f32).enumerate() {
            let bit = 1u64 << index;
            let (dot, length_squared) = to_point(viewer, &p);
            for l in 0..N {
                let ahead = dot[l] > 0.0;
                let wide = dot[l] * dot[l] < reach_squared * length_squared[l];
                let inside = if reach >= 0.0 {
                    ahead & !wide
                } else {
                    ahead | wide
                };
                weight[l] = if inside { 1.0 } else { 0.0 };
                members[l] += weight[l];
            }
            if weight
                .iter()
                .fold(0u32, |found, w| found | u32::from(*w != 0.0))
                != 0
            {
                present |= bit;
            }
        }
        // Without `skip_absent` every viewer takes part in what follows (the plain computation).
        let present = if skip_absent {
            present
        } else {
            lanes_where(weights.len(), |_| true)
        };
        let any = lanes_where(N, |l| members[l] > 0.0);
        if self.mode == ViewerMode::Zones {
            for weight in weights.iter_mut() {
                for l in 0..N {
                    let share = if members[l] > 0.0 {
                        1.0 / members[l]
                    } else {
                        0.0
                    };
                    weight[l] *= share;
                }
            }
            return (any, present);
        }
        if !members.iter().any(|m| *m > 1.0) {
            return (any, present);
        }
        // Points in several cones: weights from the angles. A viewer whose cone holds no point
        // keeps its weights of 0 (adding them to the total changes no bit: the total is +0 or
        // more).
        let mut total = [0.0f32; N];
        for (index, (weight, viewer)) in weights.iter_mut().zip(&self.viewers_f32).enumerate() {
            if present & (1 << index) == 0 {
                continue;
            }
            let a = angles(viewer, &p);
            for l in 0..N {
                let a = a[l] * self.inv_cutoff;
                let raw = match self.weighting {
                    ViewerWeighting::Cosine => cos(a),
                    _ => 1.0 - a,
                };
                let blended = if weight[l] > 0.0 { max(raw, 0.0) } else { 0.0 };
                // A select, not a branch: a masked store per vector is slow on some CPUs.
                weight[l] = if members[l] > 1.0 { blended } else { weight[l] };
                total[l] += weight[l];
            }
        }
        let any = lanes_where(N, |l| total[l] > 0.0);
        for (index, weight) in weights.iter_mut().enumerate() {
            if present & (1 << index) == 0 {
                continue; // 0 divided stays 0
            }
            for l in 0..N {
                // Divided, not multiplied by a reciprocal, so that a viewer alone gets exactly 1.
                weight[l] /= if total[l] > 0.0 { total[l] } else { 1.0 };
            }
        }
        (any, present)
    }

    /// [`Self::cameras`] for one screen point.
    #[cfg(test)]
    pub(crate) fn camera_at(&self, point: DVec3, st: DVec2, needs_right: bool) -> (DVec3, DVec3) {
        self.cameras(&[point], &[st], needs_right, Isa::Baseline)[0]
    }

    /// [`Self::cameras_into`], returned as (camera position, right vector) per point.
    #[inline]
    pub(crate) fn cameras<const N: usize>(
        &self,
        points: &[DVec3; N],
        st: &[DVec2; N],
        needs_right: bool,
        isa: Isa,
    ) -> [CameraAt; N] {
        let mut lanes = CameraLanes::default();
        self.cameras_into(points, st, needs_right, isa, &mut lanes);
        std::array::from_fn(|l| (lanes.head_at(l), lanes.right_at(l)))
    }

    /// The camera positions and right vectors (blended ones unused, and not computed, when
    /// `needs_right` is false) for `N` screen points at once (four for single rays, a frame's
    /// block) into `cameras`, lane by lane; the points' screen coordinates (after imageRegion)
    /// are `st`. On path `isa` where this CPU has it, else the baseline one; the same bits on
    /// every path.
    #[inline]
    pub(crate) fn cameras_into<const N: usize>(
        &self,
        points: &[DVec3; N],
        st: &[DVec2; N],
        needs_right: bool,
        isa: Isa,
        cameras: &mut CameraLanes<N>,
    ) {
        if self.mode == ViewerMode::Tiles {
            // A frame's block nearly always lies in one tile: its camera is looked up once.
            // Tiles grow with s and t, so the points share a tile when their smallest and
            // largest coordinates do (NaN, which takes tile 0, is never smallest or largest:
            // such blocks go point by point).
            let (mut low, mut high, mut nan) = (st[0], st[0], false);
            for st in st {
                low = DVec2::new(
                    if st.x < low.x { st.x } else { low.x },
                    if st.y < low.y { st.y } else { low.y },
                );
                high = DVec2::new(
                    if st.x > high.x { st.x } else { high.x },
                    if st.y > high.y { st.y } else { high.y },
                );
                nan |= st.is_nan();
            }
            let first = self.tile_of(low);
            if !nan && self.tile_of(high) == first {
                let (head, right) = self.tile_camera(first, needs_right);
                for axis in 0..3 {
                    cameras.head[axis] = [head[axis]; N];
                    cameras.right[axis] = [right[axis]; N];
                }
                return;
            }
            for (l, st) in st.iter().enumerate() {
                let (head, right) = self.tile_camera(self.tile_of(*st), needs_right);
                cameras.set(l, head, right);
            }
            return;
        }
        self.cameras_on(isa, points, needs_right, true, cameras)
    }

    /// [`Self::cameras_into`]'s perPixel and zones cameras on path `isa` where this CPU has it
    /// (else the baseline); `skip_absent`: viewers whose cone holds none of the points skip
    /// their angles and blend (the same bits either way).
    #[inline]
    fn cameras_on<const N: usize>(
        &self,
        isa: Isa,
        points: &[DVec3; N],
        needs_right: bool,
        skip_absent: bool,
        cameras: &mut CameraLanes<N>,
    ) {
        match isa {
            // SAFETY: this CPU has the path (checked in the guard; the checks are cached loads).
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 if isa.supported() => unsafe {
                self.cameras_avx512(points, needs_right, skip_absent, cameras)
            },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 if isa.supported() => unsafe {
                self.cameras_avx2(points, needs_right, skip_absent, cameras)
            },
            _ => self.cameras_at_points(points, needs_right, skip_absent, cameras),
        }
    }

    /// [`Self::cameras_into`]'s perPixel and zones cameras with every viewer's angles and
    /// blend computed (none skipped), on path `isa`; and the mask of viewers whose cone holds
    /// some of the points, for tests comparing the two.
    #[cfg(test)]
    fn cameras_without_skips<const N: usize>(
        &self,
        points: &[DVec3; N],
        needs_right: bool,
        isa: Isa,
        cameras: &mut CameraLanes<N>,
    ) -> u64 {
        self.cameras_on(isa, points, needs_right, false, cameras);
        let mut weights = [[0.0; N]; MAX_VIEWERS];
        self.weights_of(points, &mut weights, true).1
    }

    crate::isa::avx2_and_avx512! {
        fn [cameras_avx2, cameras_avx512]<const N: usize>(
            &self,
            points: &[DVec3; N],
            needs_right: bool,
            skip_absent: bool,
            cameras: &mut CameraLanes<N>,
        ) {
            self.cameras_at_points(points, needs_right, skip_absent, cameras)
        }
    }

    /// The (column, row) of the tile holding screen coordinates `st`.
    #[inline]
    fn tile_of(&self, st: DVec2) -> (u32, u32) {
        // Truncation is floor for these non-negative values (and needs no libm call).
        let tile = |coordinate: f64, tiles: u32| {
            ((coordinate * f64::from(tiles)).max(0.0) as u32).min(tiles - 1)
        };
        (tile(st.x, self.tiles[0]), tile(st.y, self.tiles[1]))
    }

    /// The camera of tile (column, row).
    #[inline]
    fn tile_camera(&self, (column, row): (u32, u32), needs_right: bool) -> CameraAt {
        match self
            .tile_cameras
            .get((row * self.tiles[0] + column) as usize)
        {
            Some(camera) => *camera,
            None => self.camera_at_point(self.tile_centre(column, row), needs_right),
        }
    }

    fn camera_at_point(&self, point: DVec3, needs_right: bool) -> (DVec3, DVec3) {
        let mut lanes = CameraLanes::<4>::default();
        self.cameras_at_points(&[point; 4], needs_right, true, &mut lanes);
        (lanes.head_at(0), lanes.right_at(0))
    }

    /// The cameras for the weights at `N` screen points: `Σ ŵ_i H_i` in f32; exactly `H_i`
    /// and `R_i` where viewer `i`'s weight is 1.
    #[inline(always)]
    fn cameras_at_points<const N: usize>(
        &self,
        points: &[DVec3; N],
        needs_right: bool,
        skip_absent: bool,
        cameras: &mut CameraLanes<N>,
    ) {
        // Working memory sized for the viewers there are (it is set up for every call).
        match self.heads.len() {
            0..=4 => self.cameras_with::<4, N>(points, needs_right, skip_absent, cameras),
            5..=16 => self.cameras_with::<16, N>(points, needs_right, skip_absent, cameras),
            _ => self.cameras_with::<MAX_VIEWERS, N>(points, needs_right, skip_absent, cameras),
        }
    }

    /// Lane by lane with selects rather than a branch per point, so that the compiler makes
    /// it SIMD: the blend, then where a viewer's weight is 1 (every other one's is then 0) that
    /// viewer's own head and right vector, and where no viewer has a say the mean of all.
    #[inline(always)]
    fn cameras_with<const V: usize, const N: usize>(
        &self,
        points: &[DVec3; N],
        needs_right: bool,
        skip_absent: bool,
        cameras: &mut CameraLanes<N>,
    ) {
        let mut weights = [[0.0; N]; V];
        let (any, present) = self.weights_of(points, &mut weights, skip_absent);
        let mut head = [[0.0f32; N]; 3];
        let mut right = [[0.0f32; N]; 3];
        // Viewers of weight 0 at every point add nothing (the sums are +0 or more).
        for (index, (weight, viewer)) in weights.iter().zip(&self.viewers_f32).enumerate() {
            if present & (1 << index) == 0 {
                continue;
            }
            for (sum, component) in head.iter_mut().zip(viewer.head) {
                for l in 0..N {
                    sum[l] += weight[l] * component;
                }
            }
            if needs_right {
                for (sum, component) in right.iter_mut().zip(viewer.right) {
                    for l in 0..N {
                        sum[l] += weight[l] * component;
                    }
                }
            }
        }
        for (lanes, sum) in cameras.head.iter_mut().zip(&head) {
            for l in 0..N {
                lanes[l] = f64::from(sum[l]);
            }
        }
        if needs_right {
            for l in 0..N {
                let blended =
                    DVec3::new(right[0][l].into(), right[1][l].into(), right[2][l].into())
                        .try_normalize()
                        .unwrap_or(self.screen.x);
                for (axis, lanes) in cameras.right.iter_mut().enumerate() {
                    lanes[l] = blended[axis];
                }
            }
        } else {
            for (axis, lanes) in cameras.right.iter_mut().enumerate() {
                lanes.fill(self.screen.x[axis]);
            }
        }
        for (index, weight) in weights.iter().enumerate().take(self.heads.len()) {
            // Usually no point is one viewer's alone: one vector test spares the selects.
            if present & (1 << index) != 0
                && weight
                    .iter()
                    .fold(0u32, |found, w| found | u32::from(*w == 1.0))
                    != 0
            {
                cameras.set_where(|l| weight[l] == 1.0, self.heads[index], self.rights[index]);
            }
        }
        if any.count_ones() as usize != N {
            cameras.set_where(|l| any & (1 << l) == 0, self.mean_head, self.mean_right);
        }
    }

    /// Screen point at the centre of tile (`column`, `row`). The centre's coordinates are
    /// computed as the frame computes pixel centres, so one tile per pixel gives exactly the
    /// perPixel points.
    fn tile_centre(&self, column: u32, row: u32) -> DVec3 {
        let centre = |index: u32, tiles: u32| f64::from((index as f32 + 0.5) / tiles as f32);
        let s = centre(column, self.tiles[0]);
        let t = centre(row, self.tiles[1]);
        let screen = &self.screen;
        screen.lower_left
            + s * (screen.lower_right - screen.lower_left)
            + t * (screen.upper_right - screen.lower_right)
    }
}

/// Per lane, `gaze·(P − head)` and `|P − head|²` of a viewer and the points `P` (x, y, z).
#[inline(always)]
fn to_point<const N: usize>(viewer: &ViewerF32, p: &[[f32; N]; 3]) -> ([f32; N], [f32; N]) {
    let [hx, hy, hz] = viewer.head;
    let [gx, gy, gz] = viewer.gaze;
    let mut dot = [0.0; N];
    let mut length_squared = [0.0; N];
    for l in 0..N {
        let (vx, vy, vz) = (p[0][l] - hx, p[1][l] - hy, p[2][l] - hz);
        dot[l] = gx * vx + gy * vy + gz * vz;
        length_squared[l] = vx * vx + vy * vy + vz * vz;
    }
    (dot, length_squared)
}

/// Per lane, the angle between a viewer's gaze and the point from its head.
#[inline(always)]
fn angles<const N: usize>(viewer: &ViewerF32, p: &[[f32; N]; 3]) -> [f32; N] {
    let (dot, length_squared) = to_point(viewer, p);
    let mut angle = [0.0; N];
    for l in 0..N {
        angle[l] = acos(min(max(dot[l] / length_squared[l].sqrt(), -1.0), 1.0));
    }
    angle
}

/// The lanes (of `n`) where `test` holds, as bits.
#[inline(always)]
fn lanes_where(n: usize, test: impl Fn(usize) -> bool) -> u64 {
    (0..n).fold(0, |bits, l| bits | (u64::from(test(l)) << l))
}

/// The larger of two values as a SIMD max instruction computes it (`b` when either is NaN).
#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// The smaller of two values as a SIMD min instruction computes it (`b` when either is NaN).
#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// `acos` of a value in `[-1, 1]`, absolute error below 5·10⁻⁷ (Abramowitz & Stegun 4.4.46
/// on |x|, 2·10⁻⁸, mirrored for negative x; the rest is f32 rounding).
// The published coefficients as printed (f32 rounds them).
#[allow(clippy::excessive_precision)]
#[inline(always)]
fn acos(x: f32) -> f32 {
    let a = min(x.abs(), 1.0);
    let mut poly = -0.001_262_491_1f32;
    for coefficient in [
        0.006_670_090_1,
        -0.017_088_125_6,
        0.030_891_881,
        -0.050_174_304_6,
        0.088_978_987_4,
        -0.214_598_801_6,
        1.570_796_305,
    ] {
        poly = poly * a + coefficient;
    }
    let positive = max(1.0 - a, 0.0).sqrt() * poly;
    if x < 0.0 {
        std::f32::consts::PI - positive
    } else {
        positive
    }
}

/// `cos` of a value in `[0, π/2]` (Taylor series to x¹², error below 10⁻⁸).
#[inline(always)]
fn cos(x: f32) -> f32 {
    let y = x * x;
    let mut sum = 1.0f32 / 479_001_600.0;
    for coefficient in [
        -1.0 / 3_628_800.0,
        1.0 / 40_320.0,
        -1.0 / 720.0,
        1.0 / 24.0,
        -0.5,
        1.0,
    ] {
        sum = sum * y + coefficient;
    }
    sum
}

/// `ln erfc(x)` for `x ≥ 0`, relative error of erfc below 1.2·10⁻⁷ (the Chebyshev fit
/// `erfc(x) ≈ t·exp(−x² + P(t))`, `t = 1/(1 + x/2)`, of Press et al., Numerical Recipes); in
/// log form it never underflows.
#[allow(clippy::excessive_precision)]
fn ln_erfc(x: f32) -> f32 {
    let x = f64::from(x.max(0.0));
    let t = 1.0 / (1.0 + 0.5 * x);
    let mut poly = 0.170_872_77;
    for coefficient in [
        -0.822_152_23,
        1.488_515_87,
        -1.135_203_98,
        0.278_868_07,
        -0.186_288_06,
        0.096_784_18,
        0.374_091_96,
        1.000_023_68,
        -1.265_512_23,
    ] {
        poly = poly * t + coefficient;
    }
    (t.ln() - x * x + poly) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn screen() -> ScreenFrame {
        // The front wall of a 3 m CAVE centred on the origin, floor at y = 0.
        ScreenFrame::new(
            DVec3::new(-1.5, 0.0, -1.5),
            DVec3::new(1.5, 0.0, -1.5),
            DVec3::new(1.5, 3.0, -1.5),
        )
        .unwrap()
    }

    #[test]
    fn polynomial_acos_cos_and_erfc_match_the_library_functions() {
        for i in 0..=2000 {
            let x = -1.0 + i as f32 / 1000.0;
            let ours = acos(x);
            assert!((ours - x.acos()).abs() < 5e-7, "acos({x}): {ours}");
            let angle = i as f32 / 2000.0 * std::f32::consts::FRAC_PI_2;
            assert!((cos(angle) - angle.cos()).abs() < 2e-7);
        }
        // erfc at known values (Abramowitz & Stegun table 7.1).
        for (x, erfc) in [
            (0.0, 1.0),
            (0.5, 0.479_500_122),
            (1.0, 0.157_299_207),
            (2.0, 4.677_734_98e-3),
            (3.0, 2.209_049_70e-5),
        ] {
            let ours = f64::from(ln_erfc(x)).exp();
            assert!((ours / erfc - 1.0).abs() < 1e-6, "erfc({x}): {ours}");
        }
        // Far in the tail erfc(x) ≈ exp(−x²)/(x√π): finite logs, no underflow.
        let tail = ln_erfc(30.0);
        let expected = -900.0 - (30.0 * std::f64::consts::PI.sqrt()).ln();
        assert!((f64::from(tail) - expected).abs() < 1e-3, "{tail}");
    }

    #[test]
    fn weights_follow_the_definitions_and_sum_to_one() {
        let heads = vec![Vec3::new(-0.5, 1.7, 0.0), Vec3::new(0.6, 1.6, 0.3)];
        let gazes = vec![Vec3::new(0.0, 0.0, -1.0), Vec3::new(-0.3, 0.1, -1.0)];
        let cutoff = 0.6f32;
        for weighting in [
            ViewerWeighting::Linear,
            ViewerWeighting::Cosine,
            ViewerWeighting::Gaussian,
        ] {
            let set = ViewerSet::new(
                &ViewerDesc {
                    weighting,
                    cutoff_angle: cutoff,
                    ..ViewerDesc::new(heads.clone(), gazes.clone())
                },
                screen(),
                0.0,
            )
            .unwrap();
            let mut checked = 0;
            for i in 0..20 {
                for j in 0..20 {
                    let p = DVec3::new(
                        -1.45 + 0.15 * f64::from(i),
                        0.05 + 0.15 * f64::from(j),
                        -1.5,
                    );
                    let raw: Vec<f64> = (0..2)
                        .map(|v| {
                            let to = p - heads[v].as_dvec3();
                            let a = gazes[v].as_dvec3().normalize().dot(to.normalize()).acos();
                            let c = f64::from(cutoff);
                            match weighting {
                                ViewerWeighting::Linear => (1.0 - a / c).max(0.0),
                                ViewerWeighting::Cosine if a < c * std::f64::consts::FRAC_PI_2 => {
                                    (a / c).cos()
                                }
                                ViewerWeighting::Cosine => 0.0,
                                // erfc(3a/(c√2)) relative to each other via their logs.
                                ViewerWeighting::Gaussian => {
                                    f64::from(ln_erfc((3.0 * a / (c * 2f64.sqrt())) as f32))
                                }
                            }
                        })
                        .collect();
                    let expected: Vec<f64> = if weighting == ViewerWeighting::Gaussian {
                        let top = raw[0].max(raw[1]);
                        let w: Vec<f64> = raw.iter().map(|l| (l - top).exp()).collect();
                        let sum: f64 = w.iter().sum();
                        w.iter().map(|w| w / sum).collect()
                    } else {
                        let sum: f64 = raw.iter().sum();
                        raw.iter()
                            .map(|w| if sum > 0.0 { w / sum } else { 0.0 })
                            .collect()
                    };
                    let mut weights = [0.0; MAX_VIEWERS];
                    let any = set.weights_at(p, &mut weights);
                    assert_eq!(any, expected.iter().sum::<f64>() > 0.0, "{weighting:?} {p}");
                    if any {
                        let sum: f32 = weights[..2].iter().sum();
                        assert!((sum - 1.0).abs() < 1e-6, "{weighting:?}: sum {sum}");
                        for v in 0..2 {
                            assert!(
                                (f64::from(weights[v]) - expected[v]).abs() < 2e-5,
                                "{weighting:?} {p}: {:?} vs {expected:?}",
                                &weights[..2]
                            );
                        }
                        checked += 1;
                    }
                }
            }
            assert!(checked > 100, "{weighting:?}: {checked}");
        }
    }

    #[test]
    fn the_papers_example_normalises_three_quarters_and_a_half() {
        // Viewer 0 looks at the point at a quarter of the cutoff (linear weight 0.75),
        // viewer 1 at half of it (0.5): normalised 0.6 and 0.4.
        let point = DVec3::new(0.0, 1.5, -1.5);
        let cutoff = 0.8f64;
        let head = |angle: f64, side: f64| {
            // Head 1.5 m in front of the point, gaze rotated by `angle` about the vertical.
            let head = point + DVec3::new(side, 0.0, 1.5);
            let to_point = (point - head).normalize();
            let (sin, cos) = (side.signum() * angle).sin_cos();
            let gaze = DVec3::new(
                to_point.x * cos - to_point.z * sin,
                0.0,
                to_point.x * sin + to_point.z * cos,
            );
            (head.as_vec3(), gaze.as_vec3())
        };
        let (h0, g0) = head(0.25 * cutoff, 0.3);
        let (h1, g1) = head(0.5 * cutoff, -0.4);
        let set = ViewerSet::new(
            &ViewerDesc {
                cutoff_angle: cutoff as f32,
                ..ViewerDesc::new(vec![h0, h1], vec![g0, g1])
            },
            screen(),
            0.0,
        )
        .unwrap();
        let mut weights = [0.0; MAX_VIEWERS];
        assert!(set.weights_at(point, &mut weights));
        assert!((weights[0] - 0.6).abs() < 1e-5 && (weights[1] - 0.4).abs() < 1e-5);
        let (camera, _) = set.camera_at(point, DVec2::ZERO, true);
        let expected = 0.6 * h0.as_dvec3() + 0.4 * h1.as_dvec3();
        assert!(
            (camera - expected).length() < 1e-5,
            "{camera} vs {expected}"
        );
    }

    /// Blocks of 8×8 pixel centres (`width` × `height` pixels, optionally jittered inside
    /// their pixels) on `screen`, lane by lane as the frame's blocks hold them.
    fn pixel_blocks(
        screen: &ScreenFrame,
        width: u32,
        height: u32,
        jitter: u64,
    ) -> Vec<[DVec3; 64]> {
        let mut state = jitter;
        let mut unit = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            if jitter == 0 {
                0.5
            } else {
                (state >> 40) as f64 / (1u64 << 24) as f64
            }
        };
        let mut blocks = Vec::new();
        for by in (0..height).step_by(8) {
            for bx in (0..width).step_by(8) {
                blocks.push(std::array::from_fn(|l| {
                    let (x, y) = (bx + l as u32 % 8, by + l as u32 / 8);
                    let s = (f64::from(x) + unit()) / f64::from(width);
                    let t = (f64::from(y) + unit()) / f64::from(height);
                    screen.lower_left
                        + s * (screen.lower_right - screen.lower_left)
                        + t * (screen.upper_right - screen.lower_right)
                }));
            }
        }
        blocks
    }

    #[test]
    fn blocks_skipping_viewers_outside_their_cones_get_the_cameras_of_every_viewer_computed() {
        // The render benchmark's screen (1 m from the tracked head, 0.9 rad wide) with its
        // heads and gazes, and a CAVE wall with three people looking at different parts of it.
        let eye = DVec3::new(0.0, 1.2, 1.6);
        let forward = (-eye).normalize();
        let x = forward.cross(DVec3::Y).normalize();
        let y = x.cross(forward);
        let half = 0.45f64.tan();
        let corner = |a: f64, b: f64| eye + forward + x * (a * half) + y * (b * half);
        let bench_screen =
            ScreenFrame::new(corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0)).unwrap();
        let bench_viewers = |count: usize| {
            let offsets = [(-1.0, -0.5), (1.0, -0.5), (-1.0, 0.5), (1.0, 0.5)];
            let heads: Vec<Vec3> = offsets[..count]
                .iter()
                .map(|(a, b)| (eye + x * (0.25 * a) + y * (0.15 * b)).as_vec3())
                .collect();
            let gazes = offsets[..count]
                .iter()
                .zip(&heads)
                .map(|((a, b), h)| {
                    (eye + forward + x * (0.25 * a) + y * (0.2 * b) - h.as_dvec3()).as_vec3()
                })
                .collect();
            ViewerDesc::new(heads, gazes)
        };
        let cave_viewers = ViewerDesc::new(
            vec![
                Vec3::new(-0.5, 1.7, 0.3),
                Vec3::new(0.6, 1.6, -0.2),
                Vec3::new(0.0, 1.2, 0.9),
            ],
            vec![
                Vec3::new(-0.6, -0.3, -1.8),
                Vec3::new(0.9, -0.3, -1.2),
                Vec3::new(0.2, 0.4, -1.0),
            ],
        );
        let with = |desc: ViewerDesc, mode, weighting, cutoff_angle| ViewerDesc {
            mode,
            weighting,
            cutoff_angle,
            ..desc
        };
        use ViewerMode::{PerPixel, Zones};
        use ViewerWeighting::{Cosine, Gaussian, Linear};
        let wide = std::f32::consts::FRAC_PI_4;
        // (viewers, screen, whether some block has a viewer whose cone holds none of its
        // points, so that its angles are skipped)
        let cases = [
            (
                with(bench_viewers(2), PerPixel, Linear, wide),
                bench_screen,
                false,
            ),
            (
                with(bench_viewers(4), PerPixel, Linear, wide),
                bench_screen,
                false,
            ),
            (
                with(bench_viewers(4), PerPixel, Linear, 0.3),
                bench_screen,
                true,
            ),
            (
                with(bench_viewers(4), Zones, Linear, 0.3),
                bench_screen,
                true,
            ),
            (
                with(cave_viewers.clone(), PerPixel, Linear, 0.6),
                screen(),
                true,
            ),
            (
                with(cave_viewers.clone(), PerPixel, Cosine, 0.4),
                screen(),
                true,
            ),
            (
                with(cave_viewers.clone(), Zones, Linear, 0.5),
                screen(),
                true,
            ),
            // Cones wider than a right angle (a few blocks lie outside one of them) and the
            // gaussian fall-off (no cone test, every viewer has a share: nothing skipped).
            (
                with(cave_viewers.clone(), PerPixel, Linear, 1.7),
                screen(),
                true,
            ),
            (
                with(bench_viewers(4), PerPixel, Gaussian, 0.3),
                bench_screen,
                false,
            ),
        ];
        for (index, (desc, screen, skips)) in cases.into_iter().enumerate() {
            let set = ViewerSet::new(&desc, screen, 0.0).unwrap();
            let count = desc.positions.len();
            let every = (1u64 << count) - 1;
            let (mut skipping, mut blocks) = (0, 0);
            for jitter in [0, 3] {
                for points in pixel_blocks(&screen, 320, 200, jitter) {
                    for needs_right in [false, true] {
                        for isa in crate::isa::test_paths() {
                            let mut skipped = CameraLanes::<64>::default();
                            let mut tested = CameraLanes::<64>::default();
                            set.cameras_into(
                                &points,
                                &[DVec2::ZERO; 64],
                                needs_right,
                                isa,
                                &mut skipped,
                            );
                            let present =
                                set.cameras_without_skips(&points, needs_right, isa, &mut tested);
                            let bits = |lanes: &CameraLanes<64>| {
                                [lanes.head, lanes.right]
                                    .map(|axes| axes.map(|l| l.map(f64::to_bits)))
                            };
                            assert!(
                                bits(&skipped) == bits(&tested),
                                "case {index}: viewers present {present:b}, right {needs_right}, isa {isa:?}"
                            );
                            if needs_right || isa.has_avx2() {
                                continue;
                            }
                            blocks += 1;
                            skipping += usize::from(present != every);
                        }
                    }
                }
            }
            assert_eq!(blocks, 2 * 40 * 25, "case {index}");
            assert_eq!(skipping > 0, skips, "case {index}: {skipping} of {blocks}");
        }
    }

    #[test]
    fn bad_viewers_are_reported_with_parameter_and_index() {
        let heads = vec![Vec3::new(0.0, 1.7, 0.0), Vec3::new(0.5, 1.7, 0.0)];
        let gazes = vec![Vec3::NEG_Z, Vec3::NEG_Z];
        let check = |desc: ViewerDesc, parameter: &str, needle: &str| {
            let error = ViewerSet::new(&desc, screen(), 0.0).unwrap_err();
            assert_eq!(error.parameter, parameter, "{error}");
            assert!(error.message.contains(needle), "{error}");
        };
        let base = ViewerDesc::new(heads.clone(), gazes.clone());
        check(
            ViewerDesc::new(vec![], vec![]),
            "viewer.position",
            "at least one",
        );
        check(
            ViewerDesc::new(heads.clone(), vec![Vec3::NEG_Z]),
            "viewer.direction",
            "1 elements",
        );
        check(
            ViewerDesc {
                rights: Some(vec![Vec3::X]),
                ..base.clone()
            },
            "viewer.right",
            "1 elements",
        );
        check(
            ViewerDesc::new(heads.clone(), vec![Vec3::NEG_Z, Vec3::ZERO]),
            "viewer.direction",
            "viewer 1",
        );
        check(
            ViewerDesc::new(vec![heads[0], Vec3::new(f32::NAN, 0.0, 0.0)], gazes.clone()),
            "viewer.position",
            "viewer 1",
        );
        check(
            ViewerDesc::new(vec![heads[0], Vec3::new(0.0, 1.0, -1.6)], gazes.clone()),
            "viewer.position",
            "viewer 1",
        );
        check(
            ViewerDesc {
                rights: Some(vec![Vec3::X, Vec3::splat(f32::INFINITY)]),
                ..base.clone()
            },
            "viewer.right",
            "viewer 1",
        );
        for cutoff in [0.0, -0.1, f32::NAN, 4.0] {
            check(
                ViewerDesc {
                    cutoff_angle: cutoff,
                    ..base.clone()
                },
                "viewerCutoffAngle",
                "(0, π]",
            );
        }
        check(
            ViewerDesc {
                tiles: [4, 0],
                ..base.clone()
            },
            "viewerTiles",
            "1×1",
        );
        check(
            ViewerDesc::new(vec![heads[0]; 65], vec![gazes[0]; 65]),
            "viewer.position",
            "at most 64",
        );
        // In stereo a head closer to the screen than half the eye distance is refused.
        let close = ViewerDesc::new(vec![Vec3::new(0.0, 1.0, -1.48)], vec![Vec3::NEG_Z]);
        assert!(ViewerSet::new(&close, screen(), 0.0).is_ok());
        let error = ViewerSet::new(&close, screen(), 0.03).unwrap_err();
        assert!(error.message.contains("viewer 0") && error.message.contains("interpupillary"));
    }
}
