use super::*;

/// The lever rule puts the whole load on the heel behind it, on the forefoot ahead of it,
/// and shares it in between.
#[test]
fn foot_load_splits_by_the_centre_of_pressure() {
    let at = |x: f64| FootLoad { vertical_n: 600.0, cop_x_m: x }.split(-0.03, 0.15);
    assert_eq!(at(-0.05), (600.0, 0.0));
    assert_eq!(at(0.2), (0.0, 600.0));
    let (h, f) = at(0.06);
    assert!((h - 300.0).abs() < 1e-9 && (f - 300.0).abs() < 1e-9, "{h} {f}");
    assert_eq!(FootLoad::default().split(-0.03, 0.15), (0.0, 0.0));
}

/// A point's velocity is the origin's plus omega x r, and `to_local` inverts the pose.
#[test]
fn segment_points_and_frames() {
    let a: f64 = -0.4;
    let s =
        SegmentState { origin_m: [0.1, 0.9], cos_sin: (a.cos(), a.sin()), velocity_m_s: [1.0, -0.2], omega_rad_s: 2.0 };
    assert!((s.angle_rad() - 0.4).abs() < 1e-15);
    let u = [0.06, -0.2];
    let (p, v) = s.point(u);
    let h = 1e-7;
    let s2 = SegmentState {
        origin_m: [0.1 + h * 1.0, 0.9 - h * 0.2],
        cos_sin: ((a + 2.0 * h).cos(), (a + 2.0 * h).sin()),
        ..s
    };
    let (p2, _) = s2.point(u);
    assert!(((p2[0] - p[0]) / h - v[0]).abs() < 1e-5 && ((p2[1] - p[1]) / h - v[1]).abs() < 1e-5);
    let back = s.to_local(p);
    assert!((back[0] - u[0]).abs() < 1e-15 && (back[1] - u[1]).abs() < 1e-15);
}
