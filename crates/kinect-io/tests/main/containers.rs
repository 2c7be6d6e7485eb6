//! Camera container files written by other programs than ours (`fixtures/make_*.py`): the
//! same frames as their native-layout copies, and typed errors on damaged containers.

use super::properties::{damage, must_not_panic};
use super::*;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

/// Replace every occurrence of `from` by `to` (same length) in `bytes`; returns how many.
fn replace_all(bytes: &mut [u8], from: &[u8], to: &[u8]) -> usize {
    assert_eq!(from.len(), to.len());
    let mut n = 0;
    let mut at = 0;
    while let Some(k) = bytes[at..].windows(from.len()).position(|w| w == from) {
        bytes[at + k..at + k + to.len()].copy_from_slice(to);
        at += k + to.len();
        n += 1;
    }
    n
}

/// The container and its native copy give the same calibration, images and clouds.
fn assert_same_as_native(container: &Recording, native: &Recording) {
    assert_eq!(container.len(), native.len());
    let (a, b) = (container.calibration(), native.calibration());
    for (x, y) in [
        (a.depth_camera, b.depth_camera),
        (a.color_camera, b.color_camera),
    ] {
        assert_eq!((x.width, x.height), (y.width, y.height));
        for (p, q) in [(x.fx, y.fx), (x.fy, y.fy), (x.cx, y.cx), (x.cy, y.cy)] {
            assert!((p - q).abs() < 1e-9, "{x:?} vs {y:?}");
        }
        for (p, q) in x
            .distortion
            .to_opencv()
            .iter()
            .zip(y.distortion.to_opencv())
        {
            assert!((p - q).abs() < 1e-12, "{x:?} vs {y:?}");
        }
    }
    let (ta, tb) = (
        a.depth_to_color().unwrap().unwrap(),
        b.depth_to_color().unwrap().unwrap(),
    );
    assert!((ta.to_homogeneous() - tb.to_homogeneous()).abs().max() < 1e-9);
    for (ta, tb) in container.timestamps_s().zip(native.timestamps_s()) {
        // The container's clock ticks in microseconds (TimestampScale 1000 ns).
        assert!((ta - tb).abs() < 1e-6, "{ta} vs {tb}");
    }
    let mut from_container = CloudBuilder::new(a, CloudConfig::default()).unwrap();
    let mut from_native = CloudBuilder::new(b, CloudConfig::default()).unwrap();
    for i in 0..container.len() {
        let (fa, fb) = (container.frame(i).unwrap(), native.frame(i).unwrap());
        assert_eq!(fa.depth.values(), fb.depth.values(), "frame {i} depth");
        assert_eq!(fa.color.as_raw(), fb.color.as_raw(), "frame {i} colour");
        let ca = from_container.build(&fa.depth, &fa.color).unwrap();
        let cb = from_native.build(&fb.depth, &fb.color).unwrap();
        assert_eq!(ca.valid_count(), cb.valid_count());
        assert!(ca.valid_count() > ca.len() / 2, "{}", ca.valid_count());
        let ((lo_a, hi_a), (lo_b, hi_b)) = (ca.bounding_box().unwrap(), cb.bounding_box().unwrap());
        assert!((lo_a - lo_b).norm() < 1e-3 && (hi_a - hi_b).norm() < 1e-3);
        let coloured = ca.iter_valid().filter(|(_, p)| p.rgb.is_some()).count();
        assert!(coloured > ca.valid_count() / 3, "{coloured} coloured");
        assert_eq!(ca.len(), cb.len());
        for k in 0..ca.len() {
            assert_eq!(ca.point(k), cb.point(k), "frame {i} point {k}");
        }
    }
}

#[test]
fn azure_kinect_mkv_from_mkvmerge_matches_its_native_copy() {
    let mkv = Recording::open(&fixture("k4a_mjpg.mkv")).expect("open");
    assert_eq!(mkv.layout(), Layout::AzureKinect);
    assert!(mkv.entries().is_none());
    // Four depth frames, three colour frames: the last depth frame has no colour within half
    // a frame period.
    assert_eq!(mkv.len(), 3);
    assert_eq!(mkv.unpaired_depth_frames(), 1);
    // Device time = block time + K4A_START_OFFSET_NS.
    let t: Vec<f64> = mkv.timestamps_s().collect();
    assert!((t[0] - 0.200_011).abs() < 1e-9 && (t[2] - t[0] - 2.0 / 30.0).abs() < 2e-6);
    let native = Recording::open(&fixture("k4a_mjpg_native")).expect("open");
    assert_same_as_native(&mkv, &native);
}

#[test]
fn azure_kinect_tracks_are_found_by_tags_then_by_name() {
    let original = std::fs::read(fixture("k4a_mjpg.mkv")).expect("read");
    let dir = temp_dir("k4a-tags");
    let native = Recording::open(&fixture("k4a_mjpg_native")).expect("open");
    // Track names gone: the K4A_*_TRACK tags (UIDs) still find the tracks.
    let mut renamed = original.clone();
    // The Name elements (ID 0x536E, 5 bytes), not the tag names that contain the words.
    assert_eq!(
        replace_all(&mut renamed, b"\x53\x6E\x85COLOR", b"\x53\x6E\x85RGB__"),
        1
    );
    assert_eq!(
        replace_all(&mut renamed, b"\x53\x6E\x85DEPTH", b"\x53\x6E\x85D16__"),
        1
    );
    let path = dir.join("renamed.mkv");
    std::fs::write(&path, &renamed).expect("write");
    assert_same_as_native(&Recording::open(&path).expect("tags"), &native);
    // Tags gone too: nothing names a track, and the error says what was looked for.
    assert_eq!(
        replace_all(&mut renamed, b"K4A_DEPTH_TRACK", b"K4A_DEPTH_TRACX"),
        1
    );
    std::fs::write(&path, &renamed).expect("write");
    let err = Recording::open(&path)
        .expect_err("no depth track")
        .to_string();
    assert!(
        err.contains("K4A_DEPTH_TRACK") && err.contains("renamed.mkv"),
        "{err}"
    );
}

#[test]
fn azure_kinect_without_calibration_attachment_is_a_calibration_error() {
    let mut bytes = std::fs::read(fixture("k4a_mjpg.mkv")).expect("read");
    // The Attachments element's ID (and its SeekHead entry) becomes an unknown one, which
    // readers skip.
    assert_eq!(
        replace_all(
            &mut bytes,
            &[0x19, 0x41, 0xA4, 0x69],
            &[0x19, 0x41, 0xA4, 0x68]
        ),
        2
    );
    let dir = temp_dir("k4a-noattach");
    let path = dir.join("no_calibration.mkv");
    std::fs::write(&path, &bytes).expect("write");
    let err = Recording::open(&path).expect_err("no calibration");
    assert!(matches!(err, KinectError::Calibration { .. }), "{err}");
    assert!(err.to_string().contains("calibration.json"), "{err}");
    // With a calibration given, the same file opens.
    let calibration = Recording::open(&fixture("k4a_mjpg_native"))
        .expect("open")
        .calibration()
        .clone();
    let rec = Recording::open_with_calibration(&path, calibration).expect("given calibration");
    assert!(rec.frame(0).is_ok());
}

#[test]
fn truncated_azure_kinect_recordings_say_so() {
    let bytes = std::fs::read(fixture("k4a_mjpg.mkv")).expect("read");
    let dir = temp_dir("k4a-cut");
    let path = dir.join("cut.mkv");
    // Cut inside the last cluster: the cluster runs past the end of the file.
    std::fs::write(&path, &bytes[..bytes.len() - 100_000]).expect("write");
    let err = Recording::open(&path).expect_err("truncated").to_string();
    assert!(
        err.contains("cut.mkv") && err.contains("truncated"),
        "{err}"
    );
    // Not Matroska at all.
    std::fs::write(&path, b"RIFF....AVI ").expect("write");
    let err = Recording::open(&path).expect_err("not mkv");
    assert!(matches!(err, KinectError::UnknownLayout { .. }), "{err}");
}

#[test]
fn realsense_bag_from_rosbags_matches_its_native_copy() {
    // The depth unit the bag records (0.25 mm), read back as its decimal; colour 3 ms late.
    check_bag("realsense", Layout::RealSense, 0.00025, 0.003);
}

/// A fixture bag with 3 paired frames and 1 unpaired depth frame: its layout, depth unit,
/// colour lag behind depth, and the same clouds as its native copy (`NAME_native`).
fn check_bag(name: &str, layout: Layout, depth_unit_m: f64, colour_lag_s: f64) {
    let bag = Recording::open(&fixture(&format!("{name}.bag"))).expect("open");
    assert_eq!(bag.layout(), layout);
    assert_eq!(bag.len(), 3);
    assert_eq!(bag.unpaired_depth_frames(), 1);
    assert_eq!(bag.calibration().depth_unit_m, depth_unit_m);
    let lag: Vec<f64> = bag
        .color_timestamps_s()
        .zip(bag.timestamps_s())
        .map(|(c, d)| c - d)
        .collect();
    assert!(
        lag.iter().all(|l| (l - colour_lag_s).abs() < 1e-6),
        "{lag:?}"
    );
    let native = Recording::open(&fixture(&format!("{name}_native"))).expect("open");
    assert_same_as_native(&bag, &native);
}

#[test]
fn ros_driver_bag_with_aligned_depth_matches_its_native_copy() {
    // bz2 chunks; an unaligned depth topic is in the bag too and must not be taken.
    let bag = Recording::open(&fixture("realsense_ros_aligned.bag")).expect("open");
    assert_eq!(bag.layout(), Layout::RealSense);
    assert_eq!(bag.len(), 4);
    assert_eq!(
        bag.calibration().registration,
        RegistrationModel::AlreadyRegistered
    );
    let native = Recording::open(&fixture("realsense_ros_aligned_native")).expect("open");
    assert_same_as_native(&bag, &native);
}

#[test]
fn orbbec_bag_from_rosbags_matches_its_native_copy() {
    // Orbbec SDK v2's layout: custom profile and property messages, Orbbec's longer Image,
    // MJPG colour, a 0.1 mm depth unit from the recorded properties, colour 1 ms late.
    check_bag("orbbec", Layout::Orbbec, 0.1 * 1e-3, 0.001);
}

#[test]
fn orbbec_bags_refuse_what_they_cannot_read_right() {
    let bytes = std::fs::read(fixture("orbbec.bag")).expect("read");
    let dir = temp_dir("orbbec-bad");
    let path = dir.join("bad.bag");
    let open = |b: &[u8]| {
        std::fs::write(&path, b).expect("write");
        Recording::open(&path)
    };
    // (Properties sit in lz4 chunks here; mirrored streams and disparity are refused by the
    // reader's unit tests.) Without its colour profile the calibration is not known: it must be given, and the
    // colour is then decoded by its encoding name.
    let mut no_profile = bytes.clone();
    assert_eq!(
        replace_all(
            &mut no_profile,
            b"/cam/streamProfileType_2",
            b"/cam/streamProfileType_X"
        ),
        2
    );
    let err = open(&no_profile).expect_err("no profile").to_string();
    assert!(
        err.contains("bad.bag") && err.contains("colour stream profile"),
        "{err}"
    );
    let native = Recording::open(&fixture("orbbec_native")).expect("open");
    let given = Recording::open_with_calibration(&path, native.calibration().clone())
        .expect("given calibration");
    assert_eq!(
        given.frame(1).expect("frame").color.as_raw(),
        native.frame(1).expect("frame").color.as_raw()
    );
    // A bag of another camera names the topics it has.
    let mut other = bytes.clone();
    assert!(replace_all(&mut other, b"/cam/sensor_3/", b"/cam/sensor_9/") > 0);
    let err = open(&other).expect_err("no depth").to_string();
    assert!(
        err.contains("sensor_9") && err.contains("/cam/sensor_3/frameType_3"),
        "{err}"
    );
}

#[test]
fn damaged_realsense_bags_say_what_is_wrong() {
    let bytes = std::fs::read(fixture("realsense.bag")).expect("read");
    let dir = temp_dir("bag-cut");
    let path = dir.join("cut.bag");
    // A recording cut short loses the index at the end of the file.
    std::fs::write(&path, &bytes[..bytes.len() / 2]).expect("write");
    let err = Recording::open(&path).expect_err("truncated").to_string();
    assert!(err.contains("cut.bag") && err.contains("reindex"), "{err}");
    // A bag of another camera (no RealSense topics) names the topics it has.
    let mut other = bytes.clone();
    assert!(replace_all(&mut other, b"Depth_0", b"Dxpth_0") > 0);
    std::fs::write(&path, &other).expect("write");
    let err = Recording::open(&path)
        .expect_err("no depth topic")
        .to_string();
    assert!(err.contains("Dxpth_0") && err.contains("cut.bag"), "{err}");
    // A chunk that declares 4 GB uncompressed is refused before anything reserves it.
    let mut huge = bytes.clone();
    let op = find(&huge, b"\x04\x00\x00\x00op=\x05").expect("a chunk record");
    let size_field = b"\x09\x00\x00\x00size=";
    let size = find(&huge[op.saturating_sub(64)..], size_field).expect("its size field")
        + op.saturating_sub(64)
        + size_field.len();
    huge[size..size + 4].copy_from_slice(&0xF000_0000u32.to_le_bytes());
    std::fs::write(&path, &huge).expect("write");
    let err = Recording::open(&path).expect_err("huge chunk").to_string();
    assert!(
        err.contains("cut.bag") && err.contains("declares 4026531840 bytes"),
        "{err}"
    );
}

/// Where `needle` first occurs in `hay`.
fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Damage a fixture (flips at `ends`: offsets from the front, and from the back when
/// negative; then random flips and an optional cut), write it as `damaged.EXT` and open it:
/// either it opens and every frame reads or fails without a panic, or the error names the
/// file.
fn open_damaged(
    name: &str,
    ends: &[(i64, u8)],
    flips: &[(usize, u8)],
    cut: Option<usize>,
) -> Result<(), TestCaseError> {
    let mut bytes = std::fs::read(fixture(name)).expect("read");
    let n = bytes.len();
    for &(at, value) in ends {
        let at = usize::try_from(at)
            .map_or_else(|_| n - 1 - (at.unsigned_abs() as usize) % n, |a| a % n);
        bytes[at] = value;
    }
    // Most cases keep the whole file, so that damaged frames and indexes are read too.
    let bytes = damage(bytes, cut.unwrap_or(n), flips);
    let ext = Path::new(name)
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("bin");
    let dir = temp_dir("container-fuzz");
    let path = dir.join(format!("damaged.{ext}"));
    std::fs::write(&path, &bytes).expect("write");
    match Recording::open(&path) {
        Ok(recording) => recording.frames().for_each(must_not_panic),
        Err(e) => {
            let text = e.to_string();
            prop_assert!(text.contains("damaged."), "{}", text);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn damaged_azure_kinect_recordings_give_errors_not_panics(
        cut in prop::option::weighted(0.3, any::<usize>()),
        head_flips in prop::collection::vec((0i64..12_000, any::<u8>()), 0..6),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 0..3),
    ) {
        // Most of the file is frame data: aim most flips at the headers, tracks, tags and
        // attachment at the front.
        open_damaged("k4a_mjpg.mkv", &head_flips, &flips, cut)?;
    }

    #[test]
    fn damaged_realsense_bags_give_errors_not_panics(
        cut in prop::option::weighted(0.3, any::<usize>()),
        ends in prop::collection::vec((-6_000i64..8_000, any::<u8>()), 0..12),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 0..3),
    ) {
        // Headers and connection records sit at the front, the index at the back.
        open_damaged("realsense.bag", &ends, &flips, cut)?;
    }

    #[test]
    fn damaged_orbbec_bags_give_errors_not_panics(
        cut in prop::option::weighted(0.3, any::<usize>()),
        ends in prop::collection::vec((-6_000i64..8_000, any::<u8>()), 0..12),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 0..3),
    ) {
        // Connections at the front; the profiles' chunk and the index at the back.
        open_damaged("orbbec.bag", &ends, &flips, cut)?;
    }
}
