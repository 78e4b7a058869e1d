use super::*;
use crate::dead_reckoning::synthetic::SyntheticPath;
use echofield_graph::se2::wrap_angle;
use nalgebra::{Point2, Vector2};
use std::f64::consts::{FRAC_PI_2, PI};

fn beam(stamp_s: f64, angle_rad: f64) -> SonarBeam {
    SonarBeam {
        stamp_s,
        angle_rad,
        bin_size_m: 0.1,
        first_bin_range_m: 0.0,
        intensities: vec![0; 10],
    }
}

/// Ground-truth navigation of `path` sampled every 0.1 s from t = 0.
fn truth_navigation(path: &SyntheticPath, duration_s: f64) -> Navigation {
    let stamps: Vec<f64> = (0..=(duration_s * 10.0) as usize)
        .map(|i| i as f64 * 0.1)
        .collect();
    let poses: Vec<Se2> = stamps.iter().map(|&t| path.world_from_vehicle(t)).collect();
    Navigation::from_poses(&stamps, &poses, 0.0).unwrap()
}

#[test]
fn beam_frames_follow_eq_4_for_a_vehicle_moving_forward() {
    // 0.5 m/s along world y (heading 90°), sonar 0.33 m ahead, turned 180°.
    let path = SyntheticPath::Straight {
        speed_mps: 0.5,
        heading_rad: FRAC_PI_2,
    };
    let nav = truth_navigation(&path, 20.0);
    let mounting = SensorMounting {
        vehicle_from_sonar: Se2::new(0.33, 0.0, PI),
        vehicle_from_dvl: Se2::identity(),
        heading_offset_rad: 0.0,
        ..Default::default()
    };
    let beams = [beam(4.0, 0.0), beam(10.0, FRAC_PI_2), beam(16.0, -0.3)];
    let frames = reference_from_beams(&beams, &nav, &mounting, 10.0).unwrap();
    // In the reference vehicle frame the vehicle moves along +x at 0.5 m/s:
    // at t = 4 it was 3 m behind, at t = 16 3 m ahead.
    let expected = [
        (-3.0 + 0.33, 0.0, PI),
        (0.33, 0.0, PI + FRAC_PI_2),
        (3.0 + 0.33, 0.0, PI - 0.3),
    ];
    for (frame, (x, y, theta)) in frames.iter().zip(expected) {
        assert!((frame.x() - x).abs() < 1e-9, "{frame:?}");
        assert!((frame.y() - y).abs() < 1e-9, "{frame:?}");
        assert!(wrap_angle(frame.theta() - theta).abs() < 1e-9, "{frame:?}");
    }
    // Bin endpoint of eq. (3): 2 m along the beam of the last frame.
    let (px, py) = frames[2].transform_xy(2.0, 0.0);
    assert!((px - (3.33 + 2.0 * (PI - 0.3).cos())).abs() < 1e-9);
    assert!((py - 2.0 * (PI - 0.3).sin()).abs() < 1e-9);
}

/// Range from `origin` along `direction` to the line `x = wall_x` (world).
fn range_to_wall(origin: Vector2<f64>, direction: Vector2<f64>, wall_x: f64) -> Option<f64> {
    let r = (wall_x - origin.x) / direction.x;
    (direction.x > 1e-6 && r > 0.0).then_some(r)
}

/// Largest distance of the points from their total-least-squares line.
fn line_fit_max_residual(points: &[Point2<f64>]) -> f64 {
    let n = points.len() as f64;
    let mean = points.iter().map(|p| p.coords).sum::<Vector2<f64>>() / n;
    let cov = points
        .iter()
        .map(|p| (p.coords - mean) * (p.coords - mean).transpose())
        .sum::<nalgebra::Matrix2<f64>>();
    let eig = cov.symmetric_eigen();
    let k = if eig.eigenvalues[0] < eig.eigenvalues[1] {
        0
    } else {
        1
    };
    let normal = eig.eigenvectors.column(k).into_owned();
    points
        .iter()
        .map(|p| (p.coords - mean).dot(&normal).abs())
        .fold(0.0, f64::max)
}

#[test]
fn compensated_wall_points_are_collinear_and_uncompensated_ones_are_not() {
    // Turning while driving towards a wall at world x = 15 m during one
    // 13.6 s rotation.
    let path = SyntheticPath::Circle {
        speed_mps: 0.5,
        radius_m: 20.0,
    };
    let nav = truth_navigation(&path, 14.0);
    let mounting = SensorMounting {
        vehicle_from_sonar: Se2::new(0.5, 0.1, 0.2),
        vehicle_from_dvl: Se2::identity(),
        heading_offset_rad: 0.0,
        ..Default::default()
    };
    let beams: Vec<SonarBeam> = (0..200)
        .map(|i| beam(i as f64 * 0.068, wrap_angle(i as f64 * PI / 100.0)))
        .collect();
    let t_ref = 0.5 * 199.0 * 0.068;
    let compensated = reference_from_beams(&beams, &nav, &mounting, t_ref).unwrap();
    let uncompensated = uncompensated_reference_from_beams(&beams, &mounting);
    let (mut with, mut without) = (Vec::new(), Vec::new());
    for (i, b) in beams.iter().enumerate() {
        let world_from_beam = path
            .world_from_vehicle(b.stamp_s)
            .compose(&mounting.vehicle_from_sonar)
            .compose(&Se2::new(0.0, 0.0, b.angle_rad));
        let direction = world_from_beam.rotation_matrix().column(0).into_owned();
        if let Some(r) = range_to_wall(world_from_beam.translation(), direction, 15.0) {
            let (x, y) = compensated[i].transform_xy(r, 0.0);
            with.push(Point2::new(x, y));
            let (x, y) = uncompensated[i].transform_xy(r, 0.0);
            without.push(Point2::new(x, y));
        }
    }
    assert!(with.len() > 60, "{} wall hits", with.len());
    let (res_with, res_without) = (
        line_fit_max_residual(&with),
        line_fit_max_residual(&without),
    );
    // Only the linear interpolation of the 10 Hz navigation remains.
    assert!(res_with < 1e-4, "compensated residual {res_with} m");
    assert!(res_without > 1.0, "uncompensated residual {res_without} m");
    // The compensated wall is where the wall is in the reference frame.
    let reference = path.world_from_vehicle(t_ref);
    for p in &with {
        let world = reference.transform_point(p);
        assert!((world.x - 15.0).abs() < 1e-4);
    }
}

#[test]
fn bad_beams_and_times_outside_the_navigation_are_errors() {
    let nav = truth_navigation(
        &SyntheticPath::Straight {
            speed_mps: 0.3,
            heading_rad: 0.0,
        },
        10.0,
    );
    let mounting = SensorMounting::default();
    let mut beams = vec![beam(1.0, 0.0), beam(2.0, 0.1), beam(3.0, 0.2)];
    beams[1].angle_rad = f64::NAN;
    assert_eq!(
        reference_from_beams(&beams, &nav, &mounting, 2.0).unwrap_err(),
        FrontendError::input("beam 1", "angle_rad", "not finite")
    );
    beams[1].angle_rad = 0.1;
    beams[2].stamp_s = f64::NAN;
    assert_eq!(
        reference_from_beams(&beams, &nav, &mounting, 2.0).unwrap_err(),
        FrontendError::input("beam 2", "stamp_s", "not finite")
    );
    beams[2].stamp_s = 30.0;
    assert!(matches!(
        reference_from_beams(&beams, &nav, &mounting, 2.0),
        Err(FrontendError::OutsideNavigation { .. })
    ));
    assert!(matches!(
        reference_from_beams(&beams[..2], &nav, &mounting, -5.0),
        Err(FrontendError::OutsideNavigation { .. })
    ));
}
