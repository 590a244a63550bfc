use super::*;
use proptest::prelude::*;
use std::f64::consts::PI;

const MM: f64 = 1e-3;

fn round_trip_error(path: &ReferencePath, s: f64, l: f64) -> f64 {
    let q = path.to_cartesian(s, l);
    let f = path.project(q).expect("finite point projects");
    (f.s_m - s).abs().max((f.l_m - l).abs())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn round_trip_on_lines(h in -PI..PI, len in 5.0f64..300.0, u in 0.0f64..1.0, l in -4.0f64..4.0) {
        let path = PathBuilder::new(10.0, -5.0, h).line(len).build(1.0).unwrap();
        prop_assert!(round_trip_error(&path, u * len, l) < MM);
    }

    #[test]
    fn round_trip_on_arcs(
        r in 8.0f64..200.0, ang in 0.2f64..3.0, left in any::<bool>(), u in 0.0f64..1.0, lf in -1.0f64..1.0,
    ) {
        // At most ~172° of turning: beyond that a tight arc brings the path's end back within a
        // few metres of its start (r = 8 m, 262° put the end 0.5 m from a point 2.2 m beside the
        // start), and the nearest point is honestly the other one. Self-approach has its own test
        // with `project_near`.
        let angle = if left { ang } else { -ang };
        let path = PathBuilder::new(0.0, 0.0, 0.3).line(10.0).arc(r, angle).line(10.0).build(0.5).unwrap();
        let l = lf * (0.5 * r).min(3.5);
        prop_assert!(round_trip_error(&path, u * path.length(), l) < MM);
    }

    #[test]
    fn round_trip_on_clothoid_like_polylines(
        kf in -1.0f64..1.0, len in 20.0f64..120.0, u in 0.0f64..1.0, lf in -1.0f64..1.0,
    ) {
        // Up to 0.1 1/m, but never more than ~170° of turning in total (no self-approach here;
        // that case has its own test with `project_near`).
        let k1 = kf * 0.1_f64.min(3.0 / len);
        let path = PathBuilder::new(0.0, 0.0, 0.0).clothoid(len, 0.0, k1).clothoid(len, k1, 0.0).build(0.7).unwrap();
        let l = lf * (0.5 / k1.abs().max(1e-3)).min(3.5);
        prop_assert!(round_trip_error(&path, u * path.length(), l) < MM);
    }

    #[test]
    fn round_trip_on_lane_changes(off in -3.75f64..3.75, u in 0.0f64..1.0, l in -1.8f64..1.8) {
        let path = PathBuilder::new(0.0, 0.0, 0.0).line(20.0).lane_change(40.0, off).line(20.0).build(0.5).unwrap();
        prop_assert!(round_trip_error(&path, u * path.length(), l) < MM);
    }

    #[test]
    fn projection_is_continuous_around_a_sharp_corner(l in -3.0f64..3.0) {
        // A bare 90° corner: no smoothing in the geometry, the heading field does the work.
        let pts = [Point2::new(0.0, 0.0), Point2::new(20.0, 0.0), Point2::new(20.0, 20.0)];
        let path = ReferencePath::from_points(&pts).unwrap();
        let mut prev: Option<f64> = None;
        for k in 0..=400 {
            let s = 10.0 + 20.0 * k as f64 / 400.0;
            let f = path.project(path.to_cartesian(s, l)).unwrap();
            if let Some(p) = prev {
                prop_assert!((f.s_m - p).abs() < 0.2, "jump from {} to {} at s={}", p, f.s_m, s);
            }
            prev = Some(f.s_m);
        }
    }
}

#[test]
fn arc_heading_and_curvature_are_those_of_the_circle() {
    let r = 25.0;
    let path = PathBuilder::new(0.0, 0.0, 0.0).arc(r, PI / 2.0).build(0.2).unwrap();
    assert!((path.length() - r * PI / 2.0).abs() < 0.01);
    let mid = path.length() / 2.0;
    assert!((path.curvature_at(mid) - 1.0 / r).abs() < 1e-3);
    assert!((path.heading_at(mid) - PI / 4.0).abs() < 1e-3);
    let end = path.point_at(path.length());
    assert!((end.x - r).abs() < 1e-9 && (end.y - r).abs() < 1e-9);
}

#[test]
fn hint_keeps_a_vehicle_on_its_branch_of_a_hairpin() {
    // Out along y=0, a tight U-turn of radius 4, back along y=8: the two legs are 8 m apart.
    let path = PathBuilder::new(0.0, 0.0, 0.0).line(50.0).arc(4.0, PI).line(50.0).build(0.5).unwrap();
    // A point 4.5 m left of the outbound leg is nearer to the return leg (3.5 m away).
    let q = Point2::new(25.0, 4.5);
    let global = path.project(q).unwrap();
    assert!(global.s_m > 50.0, "global projection picks the nearer return leg: {global:?}");
    let tracked = path.project_near(q, 25.0, 5.0).unwrap();
    assert!((tracked.s_m - 25.0).abs() < 1e-9 && (tracked.l_m - 4.5).abs() < 1e-9, "{tracked:?}");
}

#[test]
fn points_beyond_the_ends_extrapolate_along_the_end_headings() {
    let path = PathBuilder::new(0.0, 0.0, 0.0).line(10.0).build(1.0).unwrap();
    let f = path.project(Point2::new(-3.0, 1.0)).unwrap();
    assert!((f.s_m + 3.0).abs() < 1e-12 && (f.l_m - 1.0).abs() < 1e-12);
    let g = path.project(Point2::new(14.0, -2.0)).unwrap();
    assert!((g.s_m - 14.0).abs() < 1e-12 && (g.l_m + 2.0).abs() < 1e-12);
    assert_eq!(path.to_cartesian(14.0, -2.0), Point2::new(14.0, -2.0));
}

#[test]
fn bad_points_are_rejected() {
    assert_eq!(ReferencePath::from_points(&[Point2::new(0.0, 0.0)]), Err(PathError::TooShort(1)));
    assert_eq!(
        ReferencePath::from_points(&[Point2::new(0.0, 0.0), Point2::new(0.0, 0.0)]),
        Err(PathError::TooShort(1))
    );
    assert!(matches!(
        ReferencePath::from_points(&[Point2::new(0.0, 0.0), Point2::new(f64::NAN, 1.0)]),
        Err(PathError::NotFinite { index: 1, .. })
    ));
    assert!(path_nan_projection_is_none());
}

fn path_nan_projection_is_none() -> bool {
    let path = PathBuilder::new(0.0, 0.0, 0.0).line(10.0).build(1.0).unwrap();
    path.project(Point2::new(f64::NAN, 0.0)).is_none()
}

#[test]
fn bad_segments_name_the_segment() {
    let err = PathBuilder::new(0.0, 0.0, 0.0).line(10.0).arc(-1.0, 1.0).build(0.5).unwrap_err();
    assert!(matches!(err, PathError::BadSegment { index: 1, .. }), "{err}");
    assert!(err.to_string().contains("radius_m"));
}

#[test]
fn resampling_keeps_the_shape() {
    let path = PathBuilder::new(0.0, 0.0, 0.0).arc(30.0, 1.0).build(0.1).unwrap();
    let coarse = path.resampled(2.0).unwrap();
    assert!((coarse.length() - path.length()).abs() < 0.05);
    for k in 0..10 {
        let s = path.length() * k as f64 / 10.0;
        assert!(coarse.point_at(s).dist(path.point_at(s)) < 0.05);
    }
}

/// Sizes from a file are checked before anything is allocated: a line of 1e308 m or 1e9 m, a
/// radius of 1e7 m, a curvature of 1e3, or a step that would make billions of samples.
#[test]
fn absurd_sizes_are_refused_with_the_field_and_the_bound() {
    for (seg, field) in [
        (SegmentSpec::Line { length_m: 1e308 }, "length_m"),
        (SegmentSpec::Line { length_m: 1e9 }, "length_m"),
        (SegmentSpec::Arc { radius_m: 1e7, angle_deg: 10.0 }, "radius_m"),
        (
            SegmentSpec::Clothoid { length_m: 10.0, curvature_start_1pm: 0.0, curvature_end_1pm: 1e3 },
            "curvature_end_1pm",
        ),
        (SegmentSpec::LaneChange { length_m: f64::INFINITY, offset_m: 1.0 }, "length_m"),
    ] {
        let e = seg.validate().unwrap_err().to_string();
        assert!(e.contains(field), "{seg:?}: {e}");
        let spec = PathSpec { start_x_m: 0.0, start_y_m: 0.0, start_heading_deg: 0.0, segments: vec![seg.clone()] };
        assert!(spec.builder().build(0.5).is_err(), "{seg:?}");
    }
    let e = SegmentSpec::Line { length_m: 1e9 }.validate().unwrap_err().to_string();
    assert!(e.contains("10000"), "the bound is named: {e}");
    let long = PathBuilder::new(0.0, 0.0, 0.0).line(9_000.0).line(9_000.0);
    let e = long.build(1e-5).unwrap_err().to_string();
    assert!(e.contains("samples") && e.contains("2000000"), "{e}");
    assert!(long.build(1.0).is_ok());
    let path = PathBuilder::new(0.0, 0.0, 0.0).line(100.0).build(1.0).unwrap();
    assert!(path.resampled(1e-7).is_err());
    let far = PathSpec {
        start_x_m: 1e9,
        start_y_m: 0.0,
        start_heading_deg: 0.0,
        segments: vec![SegmentSpec::Line { length_m: 1.0 }],
    };
    assert!(far.validate().unwrap_err().to_string().contains("start_x_m"));
    let many =
        PathSpec { start_x_m: 0.0, segments: vec![SegmentSpec::Line { length_m: 1.0 }; MAX_SEGMENTS + 1], ..far };
    assert!(many.validate().unwrap_err().to_string().contains("at most 1000 segments"));
}

/// Subnormal and sub-physical sizes pass every "> 0" but mean nothing: a radius of 1e-310 m made a
/// 67° heading jump within one sample. Each is refused with its field and the smallest allowed value.
#[test]
fn sizes_below_their_physical_minimum_are_refused_with_the_bound() {
    for (seg, field, bound) in [
        (SegmentSpec::Arc { radius_m: 1e-310, angle_deg: 67.0 }, "radius_m", "0.1"),
        (SegmentSpec::Arc { radius_m: 0.05, angle_deg: 90.0 }, "radius_m", "0.1"),
        (SegmentSpec::Arc { radius_m: 20.0, angle_deg: 1e-320 }, "angle_deg", "0.01"),
        (SegmentSpec::Line { length_m: 5e-324 }, "length_m", "0.001"),
        (SegmentSpec::Line { length_m: 1e-4 }, "length_m", "0.001"),
        (
            SegmentSpec::Clothoid { length_m: 1e-310, curvature_start_1pm: 0.0, curvature_end_1pm: 0.05 },
            "length_m",
            "0.001",
        ),
        (SegmentSpec::LaneChange { length_m: 1e-310, offset_m: 0.0 }, "length_m", "0.001"),
    ] {
        let e = seg.validate().unwrap_err().to_string();
        assert!(e.contains(field) && e.contains(bound), "{seg:?}: {e}");
    }
    // The smallest allowed values themselves still build.
    let path = PathBuilder::new(0.0, 0.0, 0.0).line(MIN_SEGMENT_LENGTH_M).arc(MIN_RADIUS_M, MIN_ANGLE_DEG.to_radians());
    assert!(path.build(0.5).is_ok());
}
