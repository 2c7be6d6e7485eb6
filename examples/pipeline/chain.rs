//! The chain every capture goes through, synthetic or real: per frame the textured cloud and
//! its projection image (kinect-io), the markers tracked on it (meanshift-track) and lifted
//! to 3D; then the relative angles (branch-angles) and each branch's modes (modal-estimate,
//! ours and the paper's). Frames are produced and turned into clouds on worker threads; the
//! tracker takes them in order on the calling thread.
//!
//! Shared by `examples/pipeline` and the cross-crate test `tests/pipeline_twin.rs`.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

use treemocap::branch_angles::{
    AngleConfig, Hierarchy, MarkerNode, MarkerTrack, Trajectories, branch_angles,
};
use treemocap::image::RgbImage;
use treemocap::kinect_io::{
    Calibration, CameraModel, CloudBuilder, CloudConfig, DepthImage, LiftConfig, ProjectionConfig,
    ProjectionImage, TexturedCloud, project_cloud,
};
use treemocap::meanshift_track::{MarkerInit, PixelRect, Tracker, TrackerConfig};
use treemocap::modal_estimate::{EstimateConfig, Mode, Signal, estimate};
use treemocap::nalgebra::{Isometry3, Point2, Point3, Vector3};

/// One frame as a sensor gives it.
pub struct RawFrame {
    /// Time, seconds.
    pub time_s: f64,
    /// Depth image.
    pub depth: DepthImage,
    /// Colour image.
    pub color: RgbImage,
}

/// A marker of the capture: its name, parent and first-frame window on the tracking plane.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerSpec {
    /// Marker name.
    pub id: String,
    /// Parent marker (`None` for the root, the trunk's).
    pub parent: Option<String>,
    /// Window centre on the first frame, tracking-plane pixels.
    pub center: Point2<f64>,
    /// Window side, pixels.
    pub size_px: i32,
}

/// How to turn frames into marker trajectories.
pub struct CaptureSetup {
    /// The sensor's calibration.
    pub calibration: Calibration,
    /// The camera of the projection image the markers are tracked on.
    pub plane: CameraModel,
    /// From the cloud's frame (the depth camera's) to the plane's camera.
    pub cloud_to_plane: Isometry3<f64>,
    /// The markers.
    pub markers: Vec<MarkerSpec>,
    /// Frames whose clouds are accumulated for the static reconstruction (from the first).
    pub static_frames: usize,
    /// Worker threads producing frames and clouds.
    pub threads: usize,
}

/// What tracking and lifting gave.
#[derive(Clone)]
pub struct Capture {
    /// Frame times, seconds.
    pub times_s: Vec<f64>,
    /// Markers tracked (those whose window lay on the first frame), in setup order.
    pub ids: Vec<String>,
    /// Per marker and frame, the tracked centre on the plane (pixels).
    pub centers: Vec<Vec<Option<Point2<f64>>>>,
    /// Per marker and frame, the lifted position in the cloud's frame (metres).
    pub positions_m: Vec<Vec<Option<Point3<f64>>>>,
    /// The still tree: per depth pixel, the mean of its points over the first
    /// `static_frames` frames where it is valid in at least half of them (cloud frame,
    /// metres).
    pub static_points_m: Vec<Point3<f64>>,
    /// The first frame's projection image.
    pub first_projection: RgbImage,
    /// Markers left out, with the reason.
    pub dropped: Vec<(String, String)>,
    /// Seconds spent producing frames and clouds (summed over workers).
    pub produce_s: f64,
    /// Seconds spent tracking and lifting.
    pub track_s: f64,
}

/// Run `produce` for frames `0..frames` on worker threads, build each cloud and projection
/// image there, track and lift in frame order here. `progress(done, total)` is called after
/// every frame.
///
/// # Errors
/// A message naming the frame for a frame that cannot be produced or processed, and for a
/// tracker that cannot start (no marker on the first frame).
pub fn capture(
    setup: &CaptureSetup,
    frames: usize,
    produce: &(dyn Fn(usize) -> Result<RawFrame, String> + Sync),
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Capture, String> {
    if frames < 2 {
        return Err(format!("{frames} frames: a capture needs at least 2"));
    }
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let produce_ns = AtomicUsize::new(0);
    type Item = (usize, Result<(f64, TexturedCloud, ProjectionImage), String>);
    let (tx, rx) = mpsc::sync_channel::<Item>(setup.threads.max(1) * 2);
    std::thread::scope(|scope| {
        for _ in 0..setup.threads.max(1) {
            let tx = tx.clone();
            let (next, stop, produce_ns) = (&next, &stop, &produce_ns);
            scope.spawn(move || {
                let mut builder =
                    match CloudBuilder::new(&setup.calibration, CloudConfig::default()) {
                        Ok(b) => b,
                        Err(e) => {
                            let _ = tx.send((0, Err(format!("cloud builder: {e}"))));
                            return;
                        }
                    };
                loop {
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    if i >= frames || stop.load(Ordering::SeqCst) {
                        return;
                    }
                    let t = std::time::Instant::now();
                    let item = produce(i).and_then(|raw| {
                        let cloud = builder
                            .build(&raw.depth, &raw.color)
                            .map_err(|e| format!("frame {i}: cloud: {e}"))?;
                        let projection = project_cloud(
                            &cloud,
                            &setup.plane,
                            &setup.cloud_to_plane,
                            &ProjectionConfig::default(),
                        )
                        .map_err(|e| format!("frame {i}: projection image: {e}"))?;
                        Ok((raw.time_s, cloud, projection))
                    });
                    produce_ns.fetch_add(t.elapsed().as_nanos() as usize, Ordering::SeqCst);
                    if tx.send((i, item)).is_err() {
                        return;
                    }
                }
            });
        }
        drop(tx);
        let result = consume(setup, frames, &rx, progress);
        stop.store(true, Ordering::SeqCst);
        // Drain so that no worker blocks on a full channel.
        for _ in rx.iter() {}
        result.map(|mut c| {
            c.produce_s = produce_ns.load(Ordering::SeqCst) as f64 * 1e-9;
            c
        })
    })
}

type Received = Result<(f64, TexturedCloud, ProjectionImage), String>;

fn consume(
    setup: &CaptureSetup,
    frames: usize,
    rx: &mpsc::Receiver<(usize, Received)>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Capture, String> {
    let mut pending: BTreeMap<usize, Received> = BTreeMap::new();
    let mut tracker: Option<Tracker> = None;
    let mut capture = Capture {
        times_s: Vec::with_capacity(frames),
        ids: Vec::new(),
        centers: Vec::new(),
        positions_m: Vec::new(),
        static_points_m: Vec::new(),
        first_projection: RgbImage::new(1, 1),
        dropped: Vec::new(),
        produce_s: 0.0,
        track_s: 0.0,
    };
    // The lift gathers about the same depth pixels on any plane: its radius grows with the
    // plane's resolution over the depth camera's (2 px on the depth camera's own plane).
    let lift = LiftConfig {
        radius_px: LiftConfig::default().radius_px
            * (setup.plane.fx / setup.calibration.depth_camera.fx).max(1.0),
        ..LiftConfig::default()
    };
    let mut scratch = Vec::new();
    let mut sums: Vec<Still> = Vec::new();
    let mut k = 0;
    while k < frames {
        let item = match pending.remove(&k) {
            Some(item) => item,
            None => {
                let (i, item) = rx
                    .recv()
                    .map_err(|_| format!("frame {k}: the frame workers stopped"))?;
                pending.insert(i, item);
                continue;
            }
        };
        let (time_s, cloud, projection) = item?;
        let t = std::time::Instant::now();
        let image = projection.image();
        match tracker.as_mut() {
            None => {
                let (inits, dropped) = first_windows(&setup.markers, image.width(), image.height());
                capture.dropped = dropped;
                if inits.is_empty() {
                    return Err("no marker window lies on the first frame".into());
                }
                capture.ids = inits.iter().map(|m| m.id.clone()).collect();
                capture.centers = vec![Vec::with_capacity(frames); inits.len()];
                capture.positions_m = vec![Vec::with_capacity(frames); inits.len()];
                capture.first_projection = image.clone();
                tracker = Some(
                    Tracker::new(TrackerConfig::default(), image, None, &inits)
                        .map_err(|e| format!("frame 0: tracker: {e}"))?,
                );
            }
            Some(tr) => tr
                .update(image, None)
                .map_err(|e| format!("frame {k}: tracking: {e}"))?,
        }
        let tr = tracker.as_ref().ok_or("tracker missing")?;
        for (m, track) in tr.tracks().iter().enumerate() {
            let center = track.observations.last().and_then(|o| o.center);
            capture.centers[m].push(center);
            capture.positions_m[m]
                .push(center.and_then(|c| projection.lift_with(&cloud, &c, &lift, &mut scratch)));
        }
        if k < setup.static_frames {
            if sums.is_empty() {
                sums = vec![Still::default(); cloud.source_camera().pixel_count()];
            }
            for (i, p) in cloud.iter_valid() {
                if let Some(s) = sums.get_mut(i) {
                    s.add(&p.position_m);
                }
            }
            if k + 1 == setup.static_frames.min(frames) {
                let needed = (setup.static_frames as u32).div_ceil(2).max(1);
                capture.static_points_m = sums.iter().filter_map(|s| s.point(needed)).collect();
            }
        }
        capture.times_s.push(time_s);
        capture.track_s += t.elapsed().as_secs_f64();
        k += 1;
        progress(k, frames);
    }
    Ok(capture)
}

/// Spread (standard deviation of the distance from the camera) above which a pixel of the
/// still frames is not one surface: a flying pixel mixing a branch with the background lands
/// anywhere between them from frame to frame. Metres (about 5 sigma of the Kinect V2's noise
/// at 2 m).
const STILL_SPREAD_M: f64 = 0.01;

/// One depth pixel over the still frames: sums of its positions and squared distances.
#[derive(Debug, Clone, Copy, Default)]
struct Still {
    sum: Vector3<f64>,
    sum_sq_m2: f64,
    sum_r_m: f64,
    count: u32,
}

impl Still {
    fn add(&mut self, p: &Point3<f64>) {
        let r = p.coords.norm();
        self.sum += p.coords;
        self.sum_r_m += r;
        self.sum_sq_m2 += r * r;
        self.count += 1;
    }

    /// The mean position when the pixel is valid in at least `needed` frames and steady (a
    /// surface is seen in most still frames; a flying pixel or a dropout is not).
    fn point(&self, needed: u32) -> Option<Point3<f64>> {
        if self.count < needed {
            return None;
        }
        let n = f64::from(self.count);
        let mean_r = self.sum_r_m / n;
        let var = (self.sum_sq_m2 / n - mean_r * mean_r).max(0.0);
        (var.sqrt() <= STILL_SPREAD_M).then(|| Point3::from(self.sum / n))
    }
}

/// The markers whose window lies on the first frame, and the others with the reason.
fn first_windows(
    markers: &[MarkerSpec],
    width: u32,
    height: u32,
) -> (Vec<MarkerInit>, Vec<(String, String)>) {
    let mut inits = Vec::new();
    let mut dropped = Vec::new();
    for m in markers {
        let c = m.center;
        let on = c.x.is_finite()
            && c.y.is_finite()
            && c.x >= 0.0
            && c.y >= 0.0
            && c.x <= f64::from(width) - 1.0
            && c.y <= f64::from(height) - 1.0
            && m.size_px >= 3;
        if on {
            inits.push(MarkerInit {
                id: m.id.clone(),
                window: PixelRect::centered_at(c, m.size_px, m.size_px),
            });
        } else {
            dropped.push((
                m.id.clone(),
                format!(
                    "window centre ({:.1}, {:.1}) size {} px is not on the {width}x{height} first frame",
                    c.x, c.y, m.size_px
                ),
            ));
        }
    }
    (inits, dropped)
}

/// A mode within this relative distance of an ancestor's frequency is the ancestor's.
const ANCESTOR_MODE_TOLERANCE: f64 = 0.04;

/// Fewest cycles a mode must complete in the fitted segment to be a branch's swing.
const MIN_MODE_CYCLES: f64 = 2.0;

/// The modes of one marked branch.
#[derive(Debug, Clone)]
pub struct BranchResult {
    /// The child marker (names the branch).
    pub id: String,
    /// The parent marker.
    pub parent: String,
    /// Level (1 for the children of the root).
    pub level: usize,
    /// Share of frames where the tracker followed the branch's marker (a centre, not lost).
    pub tracked_fraction: f64,
    /// Share of frames where the marker has a 3D position (lifted, and not dropped as a
    /// jump).
    pub lifted_fraction: f64,
    /// Our estimate (largest-amplitude mode of the signed angle's free decay).
    pub ours: Option<Mode>,
    /// The paper's method: FFT peak frequency and eq. (6) damping.
    pub paper: Option<(f64, Option<f64>)>,
    /// The paper method's bin width, hertz.
    pub paper_bin_hz: Option<f64>,
    /// Why a value is missing, when one is.
    pub notes: Vec<String>,
    /// The angle series fitted (times, radians), for figures.
    pub series: (Vec<f64>, Vec<Option<f64>>),
    /// Fitted segment, seconds.
    pub segment_s: Option<(f64, f64)>,
    /// The branch's test window, seconds, when one was given.
    pub window_s: Option<(f64, f64)>,
}

/// The hierarchy of the markers that were tracked, dropping markers whose parent is gone
/// (with the reason).
///
/// # Errors
/// The hierarchy's own errors (no root, two roots, a cycle, an unknown parent).
pub fn hierarchy(
    markers: &[MarkerSpec],
    tracked: &[String],
    dropped: &mut Vec<(String, String)>,
) -> Result<Hierarchy, String> {
    let mut kept: Vec<&MarkerSpec> = markers.iter().filter(|m| tracked.contains(&m.id)).collect();
    loop {
        let ids: Vec<&str> = kept.iter().map(|m| m.id.as_str()).collect();
        let orphan = kept.iter().position(|m| {
            m.parent
                .as_deref()
                .is_some_and(|p| !ids.contains(&p) && markers.iter().any(|q| q.id == p))
        });
        match orphan {
            Some(i) => {
                let m = kept.remove(i);
                dropped.push((
                    m.id.clone(),
                    format!(
                        "its parent {} is not tracked, so its branch has no angle",
                        m.parent.as_deref().unwrap_or("?")
                    ),
                ));
            }
            None => break,
        }
    }
    Hierarchy::new(
        kept.iter()
            .map(|m| MarkerNode {
                id: m.id.clone(),
                parent: m.parent.clone(),
            })
            .collect(),
    )
    .map_err(|e| format!("marker hierarchy: {e}"))
}

/// A lifted position further than this from the median of its neighbours (two frames each
/// side) is a lift that landed on another surface: a branch marker moves at most about a
/// centimetre per frame at 30 fps (3 cm at 2.5 Hz peaks at 0.5 m/s). Metres.
const JUMP_M: f64 = 0.04;

/// `positions` with the isolated jumps taken out (as gaps, filled later like any other).
fn drop_jumps(positions: &[Option<Point3<f64>>]) -> Vec<Option<Point3<f64>>> {
    let n = positions.len();
    (0..n)
        .map(|i| {
            let p = positions[i]?;
            let around: Vec<Point3<f64>> = (i.saturating_sub(2)..(i + 3).min(n))
                .filter(|&j| j != i)
                .filter_map(|j| positions[j])
                .collect();
            if around.len() < 2 {
                return Some(p);
            }
            let median = |f: fn(&Point3<f64>) -> f64| {
                let mut v: Vec<f64> = around.iter().map(f).collect();
                v.sort_by(f64::total_cmp);
                0.5 * (v[(v.len() - 1) / 2] + v[v.len() / 2])
            };
            let m = Point3::new(median(|p| p.x), median(|p| p.y), median(|p| p.z));
            ((p - m).norm() <= JUMP_M).then_some(p)
        })
        .collect()
}

/// Trajectories of the hierarchy's markers in the tree frame (`cloud_to_tree` applied).
///
/// # Errors
/// When the trajectories cannot be built (a time base that is not increasing).
pub fn trajectories(
    capture: &Capture,
    hierarchy: &Hierarchy,
    cloud_to_tree: &Isometry3<f64>,
) -> Result<Trajectories, String> {
    let markers = hierarchy
        .markers()
        .iter()
        .filter_map(|node| {
            let k = capture.ids.iter().position(|id| *id == node.id)?;
            Some(MarkerTrack {
                id: node.id.clone(),
                positions_m: drop_jumps(&capture.positions_m[k])
                    .iter()
                    .map(|p| p.map(|p| cloud_to_tree * p))
                    .collect(),
            })
        })
        .collect();
    Trajectories::new(capture.times_s.clone(), markers).map_err(|e| format!("trajectories: {e}"))
}

/// Per marker, the share of frames where the tracker gave a centre.
pub fn tracked_fractions(capture: &Capture) -> BTreeMap<String, f64> {
    capture
        .ids
        .iter()
        .zip(&capture.centers)
        .map(|(id, c)| {
            let n = c.iter().filter(|c| c.is_some()).count();
            (id.clone(), n as f64 / capture.times_s.len().max(1) as f64)
        })
        .collect()
}

/// Relative angles and modes of every branch: ours on the child marker's displacement from
/// its parent's marker along its main direction of motion (free decay, matrix pencil +
/// least squares; the signed angle component that moves most where that displacement
/// cannot be formed), the paper's on eq. (1) (FFT peak and half-power band). The series
/// kept for the figures is the signed angle. A branch with an entry in `windows_s` is measured inside that time
/// window only (its own pull-and-release test); the others on the whole record.
///
/// # Errors
/// When the angles cannot be computed at all (a hierarchy marker without a trajectory).
pub fn analyse(
    hierarchy: &Hierarchy,
    trajectories: &Trajectories,
    root_direction: Vector3<f64>,
    windows_s: &BTreeMap<String, (f64, f64)>,
    tracked: &BTreeMap<String, f64>,
) -> Result<Vec<BranchResult>, String> {
    let ours_angles = branch_angles(
        hierarchy,
        trajectories,
        &AngleConfig {
            root_direction,
            ..AngleConfig::default()
        },
    )
    .map_err(|e| format!("branch angles: {e}"))?;
    let paper_angles = branch_angles(
        hierarchy,
        trajectories,
        &AngleConfig {
            root_direction,
            ..AngleConfig::paper()
        },
    )
    .map_err(|e| format!("branch angles (paper): {e}"))?;
    let times = trajectories.times_s().to_vec();
    let mut out = Vec::new();
    let mut own: BTreeMap<String, f64> = BTreeMap::new();
    for (b, p) in ours_angles.branches.iter().zip(&paper_angles.branches) {
        let track = trajectories.marker(&b.child);
        let lifted = track.map_or(0, |t| t.positions_m.iter().filter(|p| p.is_some()).count());
        let mut result = BranchResult {
            id: b.child.clone(),
            parent: b.parent.clone(),
            level: b.level,
            tracked_fraction: tracked.get(&b.child).copied().unwrap_or(0.0),
            lifted_fraction: lifted as f64 / times.len().max(1) as f64,
            ours: None,
            paper: None,
            paper_bin_hz: None,
            notes: Vec::new(),
            series: (times.clone(), Vec::new()),
            segment_s: None,
            window_s: None,
        };
        // The signed component with the larger spread (inside the branch's window) carries
        // the swing.
        let (w0, w1) = windows_s
            .get(&b.child)
            .copied()
            .unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
        let spread = |s: &treemocap::branch_angles::Series| {
            let v: Vec<f64> = s
                .values
                .iter()
                .zip(&s.times_s)
                .filter(|(_, t)| (w0..=w1).contains(*t))
                .filter_map(|(v, _)| *v)
                .collect();
            let n = v.len().max(1) as f64;
            let mean = v.iter().sum::<f64>() / n;
            v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n
        };
        let series = match &b.signed {
            Some(s) if spread(&s.w_rad) > spread(&s.u_rad) => &s.w_rad,
            Some(s) => &s.u_rad,
            None => &b.angle_rad,
        };
        result.series.1 = series.values.clone();
        // Ours is fitted on the child's displacement from its parent's marker along its
        // main direction of motion: the angle sees only the part of a swing across the
        // chord, and a twig swinging along it (toward or away from the parent's marker)
        // leaves the angle a small, distorted copy of its motion.
        let displacement = relative_swing(trajectories, &b.parent, &b.child, &times, (w0, w1));
        let window = |signal: Signal| match windows_s.get(&b.child) {
            Some(&(start_s, end_s)) => signal.slice_time(start_s, end_s),
            None => signal,
        };
        result.window_s = windows_s.get(&b.child).copied();
        let (values, measured) = match &displacement {
            Some(d) => (
                d.clone(),
                d.iter().map(Option::is_some).collect::<Vec<bool>>(),
            ),
            None => (series.values.clone(), series.measured.clone()),
        };
        match Signal::from_measured(times.clone(), values, &measured)
            .and_then(|signal| estimate(&window(signal), &EstimateConfig::default()))
        {
            Ok(e) => {
                // A relative angle carries its ancestors' swings too (the paper's Fig. 12:
                // higher levels show more modes, the stem's among them): the branch's own
                // mode is the strongest one that is none of its ancestors'.
                // (Inside the branch's own test window its ancestors are still: no exclusion.)
                let mut ancestors = Vec::new();
                let mut at = (!windows_s.contains_key(&b.child)).then(|| b.parent.clone());
                while let Some(id) = at {
                    if let Some(f) = own.get(&id) {
                        ancestors.push(*f);
                    }
                    at = hierarchy.parent_of(&id).map(str::to_string);
                }
                let is_ancestors = |m: &Mode| {
                    ancestors
                        .iter()
                        .any(|f| (m.frequency_hz - f).abs() <= ANCESTOR_MODE_TOLERANCE * f)
                };
                // A "mode" with fewer than two cycles in the fitted segment is the fit's
                // stand-in for a slow trend, not a swing.
                let span_s = e.segment.map_or(f64::INFINITY, |s| s.end_s - s.start_s);
                let swings = |m: &Mode| m.frequency_hz * span_s >= MIN_MODE_CYCLES;
                result.ours = e
                    .modes
                    .iter()
                    .find(|m| swings(m) && !is_ancestors(m))
                    .copied();
                if result.ours.is_none() {
                    result.notes.push(if e.modes.is_empty() {
                        "ours: no mode found".to_string()
                    } else {
                        format!(
                            "ours: the fit's {} mode(s) are trends (under {MIN_MODE_CYCLES} cycles in the segment) or an ancestor's; none is the branch's own",
                            e.modes.len()
                        )
                    });
                }
                if let Some(m) = result.ours {
                    own.insert(b.child.clone(), m.frequency_hz);
                }
                result.segment_s = e.segment.map(|s| (s.start_s, s.end_s));
            }
            Err(e) => result.notes.push(format!("ours: {e}")),
        }
        match Signal::new(times.clone(), p.angle_rad.values.clone())
            .and_then(|signal| estimate(&window(signal), &EstimateConfig::paper()))
        {
            Ok(e) => {
                if let Some(h) = e.half_power {
                    result.paper = Some((h.frequency_hz, h.damping_ratio));
                    result.paper_bin_hz = Some(h.bin_width_hz);
                }
            }
            Err(e) => result.notes.push(format!("paper: {e}")),
        }
        out.push(result);
    }
    Ok(out)
}

/// The child's position relative to its parent's marker, projected on the direction it
/// moves most in `window` (the first principal axis of the relative positions there),
/// metres: one coordinate of the swing whichever way it goes, across or along the chord.
fn relative_swing(
    trajectories: &Trajectories,
    parent: &str,
    child: &str,
    times: &[f64],
    window: (f64, f64),
) -> Option<Vec<Option<f64>>> {
    let (p, c) = (trajectories.marker(parent)?, trajectories.marker(child)?);
    let rel: Vec<Option<Vector3<f64>>> = p
        .positions_m
        .iter()
        .zip(&c.positions_m)
        .map(|(a, b)| Some(b.as_ref()? - a.as_ref()?))
        .collect();
    let inside: Vec<Vector3<f64>> = rel
        .iter()
        .zip(times)
        .filter(|(_, t)| (window.0..=window.1).contains(*t))
        .filter_map(|(r, _)| *r)
        .collect();
    if inside.len() < 3 {
        return None;
    }
    let mean = inside.iter().sum::<Vector3<f64>>() / inside.len() as f64;
    let cov = inside
        .iter()
        .map(|r| (r - mean) * (r - mean).transpose())
        .sum::<treemocap::nalgebra::Matrix3<f64>>();
    let eig = treemocap::nalgebra::SymmetricEigen::try_new(cov, f64::EPSILON, 1000)?;
    let k = eig.eigenvalues.imax();
    let axis: Vector3<f64> = eig.eigenvectors.column(k).into();
    Some(
        rel.iter()
            .map(|r| r.map(|r| (r - mean).dot(&axis)))
            .collect(),
    )
}
