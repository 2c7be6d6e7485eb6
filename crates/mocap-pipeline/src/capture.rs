//! The chain every capture goes through, synthetic or real: per frame the textured cloud and
//! its projection image (kinect-io), the markers tracked on it (meanshift-track) and lifted
//! to 3D; then the relative angles (branch-angles) and each branch's modes (modal-estimate,
//! ours and the paper's). Frames are produced and turned into clouds on worker threads; the
//! tracker takes them in order on the calling thread.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

use image::RgbImage;
use kinect_io::{
    Calibration, CameraModel, CloudBuilder, CloudConfig, DepthImage, LiftConfig, ProjectionConfig,
    ProjectionImage, StillCloud, TexturedCloud, project_cloud,
};
use meanshift_track::{MAX_REVISED_FRAMES, MarkerInit, PixelRect, Track, Tracker, TrackerConfig};
use nalgebra::{Isometry3, Point2, Point3};

use crate::error::{PipelineError, Result};

/// One frame as a sensor gives it.
#[derive(Debug, Clone)]
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
#[derive(Debug, Clone)]
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
#[derive(Debug, Clone)]
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
    pub dropped: Vec<DroppedMarker>,
    /// Seconds spent producing frames and clouds (summed over workers).
    pub produce_s: f64,
    /// Seconds spent tracking and lifting.
    pub track_s: f64,
    /// Marker-frames whose centre the tracker revised after they had been lifted (an identity
    /// swap of two markers of one look, undone): they hold the revised centre and no
    /// position (that frame's cloud is gone; a gap, not the other marker's position).
    pub revised_frames: usize,
}

impl Capture {
    /// Nothing captured yet, room for `frames` frame times.
    fn empty(frames: usize) -> Self {
        Self {
            times_s: Vec::with_capacity(frames),
            ids: Vec::new(),
            centers: Vec::new(),
            positions_m: Vec::new(),
            static_points_m: Vec::new(),
            first_projection: RgbImage::new(1, 1),
            dropped: Vec::new(),
            produce_s: 0.0,
            track_s: 0.0,
            revised_frames: 0,
        }
    }
}

/// Run `produce` for frames `0..frames` on worker threads, build each cloud and projection
/// image there, track and lift in frame order here. `progress(done, total)` is called after
/// every frame.
///
/// # Errors
/// [`PipelineError::Frame`] naming the frame for a frame that cannot be produced or
/// processed, [`PipelineError::NoMarkerOnFirstFrame`] when the tracker cannot start, and
/// [`PipelineError::InvalidParameter`] for fewer than 2 frames.
pub fn capture(
    setup: &CaptureSetup,
    frames: usize,
    produce: &(dyn Fn(usize) -> Result<RawFrame> + Sync),
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Capture> {
    if frames < 2 {
        return Err(PipelineError::param(
            "frames",
            format!("{frames}; a capture needs at least 2"),
        ));
    }
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let produce_ns = AtomicUsize::new(0);
    type Item = (usize, Received);
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
                            let _ = tx.send((0, Err(PipelineError::frame(0, "cloud builder", e))));
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
                            .map_err(|e| PipelineError::frame(i, "cloud", e))?;
                        let projection = project_cloud(
                            &cloud,
                            &setup.plane,
                            &setup.cloud_to_plane,
                            &ProjectionConfig::default(),
                        )
                        .map_err(|e| PipelineError::frame(i, "projection image", e))?;
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

type Received = Result<(f64, TexturedCloud, ProjectionImage)>;

fn consume(
    setup: &CaptureSetup,
    frames: usize,
    rx: &mpsc::Receiver<(usize, Received)>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Capture> {
    let mut pending: BTreeMap<usize, Received> = BTreeMap::new();
    let mut tracker: Option<Tracker> = None;
    let mut capture = Capture::empty(frames);
    let lift = LiftConfig::for_plane(&setup.plane, &setup.calibration.depth_camera);
    let mut scratch = Vec::new();
    let mut still = StillCloud::new();
    let mut k = 0;
    while k < frames {
        let item = match pending.remove(&k) {
            Some(item) => item,
            None => {
                let (i, item) = rx
                    .recv()
                    .map_err(|_| PipelineError::WorkersStopped { index: k })?;
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
                capture.dropped.clone_from(&dropped);
                if inits.is_empty() {
                    return Err(PipelineError::NoMarkerOnFirstFrame {
                        dropped: dropped
                            .iter()
                            .map(|d| format!("{}: {}", d.id, d.reason))
                            .collect::<Vec<_>>()
                            .join("; "),
                    });
                }
                capture.ids = inits.iter().map(|m| m.id.clone()).collect();
                capture.centers = vec![Vec::with_capacity(frames); inits.len()];
                capture.positions_m = vec![Vec::with_capacity(frames); inits.len()];
                capture.first_projection = image.clone();
                tracker = Some(
                    Tracker::new(TrackerConfig::default(), image, None, &inits)
                        .map_err(|e| PipelineError::frame(0, "tracker", e))?,
                );
            }
            Some(tr) => tr
                .update(image, None)
                .map_err(|e| PipelineError::frame(k, "tracking", e))?,
        }
        let tracks = tracker.as_ref().map_or(&[][..], Tracker::tracks);
        capture.revised_frames += take_revisions(tracks, &mut capture);
        for (m, track) in tracks.iter().enumerate() {
            let center = track.observations.last().and_then(|o| o.center);
            capture.centers[m].push(center);
            capture.positions_m[m]
                .push(center.and_then(|c| projection.lift_with(&cloud, &c, &lift, &mut scratch)));
        }
        if k < setup.static_frames {
            still
                .add(&cloud)
                .map_err(|e| PipelineError::frame(k, "still cloud", e))?;
            if k + 1 == setup.static_frames.min(frames) {
                capture.static_points_m = still.points();
            }
        }
        capture.times_s.push(time_s);
        capture.track_s += t.elapsed().as_secs_f64();
        k += 1;
        progress(k, frames);
    }
    Ok(capture)
}

/// Take the centres the tracker revised in frames already recorded (at most
/// [`MAX_REVISED_FRAMES`] back); their positions become gaps. Returns how many changed.
fn take_revisions(tracks: &[Track], capture: &mut Capture) -> usize {
    let mut revised = 0;
    for (m, track) in tracks.iter().enumerate() {
        let (centers, positions) = (&mut capture.centers[m], &mut capture.positions_m[m]);
        let recorded = centers.len().min(track.observations.len());
        for f in recorded.saturating_sub(MAX_REVISED_FRAMES)..recorded {
            let now = track.observations[f].center;
            if now != centers[f] {
                centers[f] = now;
                positions[f] = None;
                revised += 1;
            }
        }
    }
    revised
}

/// The markers whose window lies on the first frame, and the others with the reason.
fn first_windows(
    markers: &[MarkerSpec],
    width: u32,
    height: u32,
) -> (Vec<MarkerInit>, Vec<DroppedMarker>) {
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
            dropped.push(DroppedMarker {
                id: m.id.clone(),
                reason: format!(
                    "window centre ({:.1}, {:.1}) size {} px is not on the {width}x{height} first frame",
                    c.x, c.y, m.size_px
                ),
            });
        }
    }
    (inits, dropped)
}

/// A marker left out of the measurement, and why.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct DroppedMarker {
    /// Marker name.
    pub id: String,
    /// Why it was left out.
    pub reason: String,
}

#[cfg(test)]
mod tests {
    use super::*;
    use meanshift_track::{Observation, TrackStatus};

    fn observation(x: f64) -> Observation {
        let c = Point2::new(x, 10.0);
        Observation {
            center: Some(c),
            window: PixelRect::centered_at(c, 9, 9),
            status: TrackStatus::Tracked,
            confidence: 1.0,
        }
    }

    #[test]
    fn revised_centres_are_taken_and_their_positions_become_gaps() {
        let xs = [1.0, 2.0, 3.0, 4.0];
        let mut capture = Capture::empty(0);
        capture.ids = vec!["A".into()];
        capture.centers = vec![xs.iter().map(|&x| Some(Point2::new(x, 10.0))).collect()];
        capture.positions_m = vec![vec![Some(Point3::new(0.0, 0.0, 1.0)); 4]];
        // The tracker has a fifth frame, and revised the third.
        let mut track = Track {
            id: "A".into(),
            observations: [1.0, 2.0, 30.0, 4.0, 5.0].map(observation).to_vec(),
        };
        assert_eq!(
            take_revisions(std::slice::from_ref(&track), &mut capture),
            1
        );
        assert_eq!(capture.centers[0][2], Some(Point2::new(30.0, 10.0)));
        assert_eq!(capture.positions_m[0][2], None);
        assert!(capture.positions_m[0][3].is_some());
        assert_eq!(
            capture.centers[0].len(),
            4,
            "the new frame is not taken here"
        );
        // Nothing revised: nothing changes.
        track.observations[2] = observation(30.0);
        assert_eq!(
            take_revisions(std::slice::from_ref(&track), &mut capture),
            0
        );
    }
}
