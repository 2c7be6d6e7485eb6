//! CSV files: round trips, line-numbered errors, and no panic on any input.

use branch_angles::csv::{
    angle_columns, angles_to_csv, read_angles_csv, read_trajectories_csv, trajectories_to_csv,
};
use branch_angles::{AngleConfig, AngleError, branch_angles, synthetic};
use proptest::prelude::*;

#[test]
fn trajectories_round_trip_exactly_with_lost_frames() {
    let tree = synthetic::two_level();
    let mut t = tree.trajectories.clone();
    t = t.map_positions(|p| p);
    let text = trajectories_to_csv(&t);
    assert!(text.starts_with("t,id,x,y,z\n0,A,0,0,0\n"));
    assert_eq!(read_trajectories_csv(&text).expect("valid"), t);
    // A lost frame is an empty position; marker-major order reads the same.
    let text = "t,id,x,y,z\n0,A,0,0,0\n0.1,A,,,\n0.2,A,1,2,3\n0,B,1,1,1\n0.2,B,2,2,2\n";
    let t = read_trajectories_csv(text).expect("valid");
    assert_eq!(t.times_s(), &[0.0, 0.1, 0.2]);
    assert!(t.marker("A").expect("A").positions_m[1].is_none());
    // B has no row at 0.1: lost there.
    assert!(t.marker("B").expect("B").positions_m[1].is_none());
    // -0 and 0 are one timestamp; no row is dropped.
    let t = read_trajectories_csv("t,id,x,y,z\n-0,A,1,2,3\n0,B,4,5,6\n").expect("valid");
    assert_eq!(t.times_s().len(), 1);
    assert!(t.markers().iter().all(|m| m.positions_m[0].is_some()));
}

#[test]
fn bad_rows_name_their_line() {
    let cases = [
        ("t,id,x,y\n", 1),
        ("t,id,x,y,z\n0,A,1,2\n", 2),
        ("t,id,x,y,z\n0,A,1,,3\n", 2),
        ("t,id,x,y,z\n0,A,1,2,3\nx,A,1,2,3\n", 3),
        ("t,id,x,y,z\n0,A,nan,2,3\n", 2),
        ("t,id,x,y,z\n0,A,1,2,inf\n", 2),
        ("t,id,x,y,z\n0,,1,2,3\n", 2),
        ("", 1),
    ];
    for (text, line) in cases {
        match read_trajectories_csv(text) {
            Err(AngleError::Csv { line: l, .. }) => assert_eq!(l, line, "{text:?}"),
            other => panic!("{text:?}: {other:?}"),
        }
    }
    assert!(matches!(
        read_trajectories_csv("t,id,x,y,z\n1,A,1,2,3\n0,A,1,2,3\n"),
        Err(AngleError::UnsortedTimestamps { .. })
    ));
    assert!(matches!(
        read_trajectories_csv("t,id,x,y,z\n1,A,1,2,3\n1,A,1,2,3\n"),
        Err(AngleError::DuplicateTimestamp { .. })
    ));
}

#[test]
fn angle_tables_round_trip_in_degrees() {
    let tree = synthetic::two_level();
    let config = AngleConfig {
        rest: tree.rest,
        ..AngleConfig::default()
    };
    let set = branch_angles(&tree.hierarchy, &tree.trajectories, &config).expect("ok");
    let text = angles_to_csv(&set.times_s, &angle_columns(&set, false));
    assert!(text.starts_with("t,C,D,E\n"));
    let table = read_angles_csv(&text).expect("valid");
    assert_eq!(table.columns.len(), 3);
    for (c, b) in table.columns.iter().zip(&set.branches) {
        for (x, y) in c.values.iter().zip(&b.angle_rad.values) {
            assert!((x.expect("known") - y.expect("known")).abs() < 1e-12);
        }
    }
    let signed = angles_to_csv(&set.times_s, &angle_columns(&set, true));
    assert!(signed.starts_with("t,C_u,C_w,D_u,D_w,E_u,E_w\n"));
    // Unknown cells are empty.
    let table = read_angles_csv("t,C\n0,\n0.1,2.5\n").expect("valid");
    assert_eq!(table.columns[0].values[0], None);
    assert!(matches!(
        read_angles_csv("t,C,C\n"),
        Err(AngleError::Csv { line: 1, .. })
    ));
    assert!(matches!(
        read_angles_csv("x,C\n"),
        Err(AngleError::Csv { .. })
    ));
    assert!(matches!(
        read_angles_csv("t,C\n0,1,2\n"),
        Err(AngleError::Csv { line: 2, .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn no_input_makes_the_readers_panic(text in "\\PC{0,200}") {
        let _ = read_trajectories_csv(&text);
        let _ = read_angles_csv(&text);
    }

    #[test]
    fn csv_shaped_noise_gives_a_result_or_a_typed_error(
        rows in prop::collection::vec(
            (
                prop_oneof![Just("0".to_string()), Just("0.5".to_string()), Just("-1".to_string()),
                    Just("NaN".to_string()), Just(String::new()), "[0-9.e-]{1,6}"],
                prop_oneof![Just("A".to_string()), Just("B".to_string()), Just(String::new()),
                    Just("a b".to_string())],
                prop::collection::vec(prop_oneof![Just(String::new()), Just("1".to_string()),
                    Just("inf".to_string()), "[0-9.e-]{1,5}"], 2..5),
            ),
            0..12,
        )
    ) {
        let mut text = String::from("t,id,x,y,z\n");
        for (t, id, xs) in rows {
            text.push_str(&format!("{t},{id},{}\n", xs.join(",")));
        }
        if let Ok(tr) = read_trajectories_csv(&text) {
            // Whatever parses survives a round trip.
            prop_assert_eq!(read_trajectories_csv(&trajectories_to_csv(&tr)).unwrap(), tr);
        }
    }
}

/// Issue 20: one coordinate of 1e300 gave angles of exactly 0 and 180 degrees, and a row for
/// a marker the hierarchy does not name became a "gap" message.
#[test]
fn absurd_coordinates_and_unnamed_markers_are_errors() {
    let e = read_trajectories_csv("t,id,x,y,z\n0,A,0,0,0\n0.1,A,1e300,0,1\n").unwrap_err();
    assert!(
        matches!(e, AngleError::CoordinateOutOfRange { value, .. } if value == 1e300),
        "{e}"
    );
    assert!(e.to_string().contains("\"A\""), "{e}");
    // A georeferenced frame (UTM northing) is fine.
    assert!(read_trajectories_csv("t,id,x,y,z\n0,A,500000,5500000,120\n").is_ok());
    let tree = synthetic::two_level();
    let mut text = trajectories_to_csv(&tree.trajectories);
    text.push_str("0,Z,1,2,3\n");
    let t = read_trajectories_csv(&text).unwrap();
    match branch_angles(&tree.hierarchy, &t, &AngleConfig::default()) {
        Err(AngleError::NotInHierarchy { id }) => assert_eq!(id, "Z"),
        other => panic!("{other:?}"),
    }
}
