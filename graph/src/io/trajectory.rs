//! Trajectory files: one pose per row.
//!
//! - TUM: `stamp_s x y z qx qy qz qw` (space separated; z = 0 and the
//!   quaternion is the yaw rotation about z), the format of the TUM RGB-D
//!   benchmark tools and `evo`.
//! - CSV: a header `stamp_s,x_m,y_m,theta_rad`, then one row per pose.
//! - KITTI-style: the 3x4 matrix `[R | t]` of the 3D pose, row-major, twelve
//!   numbers per row, no stamp (the KITTI odometry ground-truth layout).

use super::IoError;
use super::lines::{MAX_ABS_POSITION_M, Record, records};
use crate::{PoseGraph, Se2, wrap_angle};
use std::io::Write;
use std::path::Path;

/// One stamped pose `world_from_vehicle`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrajectoryPose {
    pub stamp_s: f64,
    pub pose: Se2,
}

/// The graph's nodes as a trajectory, in node order. Nodes without a stamp
/// get their dense index as stamp.
pub fn graph_trajectory(graph: &PoseGraph) -> Vec<TrajectoryPose> {
    graph
        .nodes()
        .enumerate()
        .map(|(i, n)| TrajectoryPose {
            stamp_s: n.stamp_s.unwrap_or(i as f64),
            pose: n.pose,
        })
        .collect()
}

/// Writes TUM rows.
pub fn write_tum(poses: &[TrajectoryPose], w: &mut dyn Write) -> std::io::Result<()> {
    for p in poses {
        let half = 0.5 * p.pose.theta();
        writeln!(
            w,
            "{:.6} {} {} 0 0 0 {} {}",
            p.stamp_s,
            p.pose.x(),
            p.pose.y(),
            half.sin(),
            half.cos()
        )?;
    }
    Ok(())
}

/// Writes CSV with a header row. Every field is a number, so no field
/// ever needs quoting: plain `write!` is the whole format, and the graph
/// crate stays free of a CSV dependency (`loops.csv`, with text fields,
/// uses the `csv` crate).
pub fn write_csv(poses: &[TrajectoryPose], w: &mut dyn Write) -> std::io::Result<()> {
    writeln!(w, "stamp_s,x_m,y_m,theta_rad")?;
    for p in poses {
        writeln!(
            w,
            "{:.6},{},{},{}",
            p.stamp_s,
            p.pose.x(),
            p.pose.y(),
            p.pose.theta()
        )?;
    }
    Ok(())
}

/// Writes KITTI-style rows (3x4 pose matrices, row-major).
pub fn write_kitti(poses: &[TrajectoryPose], w: &mut dyn Write) -> std::io::Result<()> {
    for p in poses {
        let (s, c) = p.pose.theta().sin_cos();
        writeln!(
            w,
            "{c} {} 0 {} {s} {c} 0 {} 0 0 1 0",
            -s,
            p.pose.x(),
            p.pose.y()
        )?;
    }
    Ok(())
}

/// Largest magnitude of a TUM time stamp, seconds (the year 5138): larger
/// values are corrupted, or stamps in nanoseconds.
pub const MAX_ABS_STAMP_S: f64 = 1e11;
/// Largest magnitude of a TUM quaternion component (they are unit
/// quaternions; a few units leaves room for unnormalised writers).
pub const MAX_ABS_QUATERNION: f64 = 1e3;

/// Reads a TUM trajectory. Lines starting with `#` are comments. The 3D
/// rotation is reduced to its yaw; stamps must be finite and strictly
/// increasing; positions within [`MAX_ABS_POSITION_M`], stamps within
/// [`MAX_ABS_STAMP_S`] and quaternion components within
/// [`MAX_ABS_QUATERNION`], so that no evaluation overflows. Errors name the
/// file, line and field.
pub fn read_tum(path: &Path) -> Result<Vec<TrajectoryPose>, IoError> {
    parse_tum(&super::read_text(path)?, path)
}

/// Parses TUM text; `path` only names the source in errors.
pub fn parse_tum(text: &str, path: &Path) -> Result<Vec<TrajectoryPose>, IoError> {
    let mut poses: Vec<TrajectoryPose> = Vec::new();
    for record in records(text) {
        let pose = tum_row(&record, path)?;
        if let Some(last) = poses.last()
            && pose.stamp_s <= last.stamp_s
        {
            return Err(IoError::parse(
                path,
                record.line,
                "stamp",
                format!(
                    "stamp {} is not after the previous one ({})",
                    pose.stamp_s, last.stamp_s
                ),
            ));
        }
        poses.push(pose);
    }
    if poses.is_empty() {
        return Err(IoError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(poses)
}

/// The fields of a TUM row, in order.
const TUM_FIELDS: [&str; 8] = ["stamp", "x", "y", "z", "qx", "qy", "qz", "qw"];

/// One TUM row `stamp x y z qx qy qz qw` (bounded values, a non-zero
/// quaternion) as a planar pose: the rotation reduced to its yaw.
fn tum_row(record: &Record, path: &Path) -> Result<TrajectoryPose, IoError> {
    // TUM rows have no tag: the first token is the stamp, so the field
    // list starts at token 0.
    if record.tokens.len() != TUM_FIELDS.len() {
        let field = TUM_FIELDS
            .get(record.tokens.len())
            .copied()
            .unwrap_or("end of line");
        return Err(IoError::parse(
            path,
            record.line,
            field,
            format!(
                "a TUM row has 8 values (stamp x y z qx qy qz qw), found {}",
                record.tokens.len()
            ),
        ));
    }
    let mut v = [0.0; 8];
    for (k, value) in v.iter_mut().enumerate() {
        let (limit, what) = match k {
            0 => (MAX_ABS_STAMP_S, "a time stamp in seconds"),
            1..=3 => (MAX_ABS_POSITION_M, "a position in metres"),
            _ => (MAX_ABS_QUATERNION, "a quaternion component"),
        };
        *value = record.bounded(path, k, TUM_FIELDS[k], limit, what)?;
    }
    record.expect_terminated(path, "qw")?;
    let [stamp_s, x, y, _z, qx, qy, qz, qw] = v;
    let norm = (qx * qx + qy * qy + qz * qz + qw * qw).sqrt();
    if norm < 1e-9 {
        return Err(IoError::parse(path, record.line, "qw", "zero quaternion"));
    }
    let yaw = (2.0 * (qw * qz + qx * qy)).atan2(1.0 - 2.0 * (qy * qy + qz * qz));
    Ok(TrajectoryPose {
        stamp_s,
        pose: Se2::new(x, y, wrap_angle(yaw)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tum_round_trip() {
        let poses: Vec<_> = (0..5)
            .map(|i| TrajectoryPose {
                stamp_s: 100.0 + i as f64 * 0.5,
                pose: Se2::new(i as f64, -2.0 * i as f64, -3.0 + 1.4 * i as f64),
            })
            .collect();
        let mut buf = Vec::new();
        write_tum(&poses, &mut buf).unwrap();
        let back = parse_tum(std::str::from_utf8(&buf).unwrap(), Path::new("t.txt")).unwrap();
        assert_eq!(back.len(), poses.len());
        for (a, b) in poses.iter().zip(&back) {
            assert!((a.stamp_s - b.stamp_s).abs() < 1e-6);
            assert!((a.pose.to_vector() - b.pose.to_vector()).norm() < 1e-12);
        }
    }

    #[test]
    fn tum_rejects_out_of_order_stamps() {
        let text = "1.0 0 0 0 0 0 0 1\n0.5 0 0 0 0 0 0 1\n";
        let err = parse_tum(text, Path::new("t.txt")).unwrap_err();
        assert_eq!(err.line(), Some(2));
        assert!(err.to_string().contains("stamp"), "{err}");
    }

    // Issue 35: a TUM value of 1e308 gave an ATE of NaN with exit status 0.
    #[test]
    fn tum_rejects_absurd_values_naming_line_and_field() {
        let text = "1.0 0 0 0 0 0 0 1\n2.0 1e308 0 0 0 0 0 1\n";
        let err = parse_tum(text, Path::new("t.txt")).unwrap_err();
        let message = err.to_string();
        assert_eq!(err.line(), Some(2));
        assert!(
            message.contains("t.txt:2") && message.contains("`x`") && message.contains("range"),
            "{message}"
        );
        let text = "1e300 0 0 0 0 0 0 1\n";
        let err = parse_tum(text, Path::new("t.txt")).unwrap_err();
        assert!(err.to_string().contains("`stamp`"), "{err}");
    }

    #[test]
    fn tum_skips_a_bom_and_refuses_a_cut_last_line() {
        let text = "\u{feff}1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n";
        assert_eq!(parse_tum(text, Path::new("t.txt")).unwrap().len(), 2);
        let cut = "1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0.7 0.7";
        let err = parse_tum(cut, Path::new("t.txt")).unwrap_err();
        assert_eq!(err.line(), Some(2));
        assert!(err.to_string().contains("`qw`"), "{err}");
    }

    #[test]
    fn kitti_row_is_rotation_and_translation() {
        let poses = [TrajectoryPose {
            stamp_s: 0.0,
            pose: Se2::new(1.5, -2.0, std::f64::consts::FRAC_PI_2),
        }];
        let mut buf = Vec::new();
        write_kitti(&poses, &mut buf).unwrap();
        let values: Vec<f64> = std::str::from_utf8(&buf)
            .unwrap()
            .split_whitespace()
            .map(|t| t.parse().unwrap())
            .collect();
        let expected = [0.0, -1.0, 0.0, 1.5, 1.0, 0.0, 0.0, -2.0, 0.0, 0.0, 1.0, 0.0];
        assert_eq!(values.len(), 12);
        for (v, e) in values.iter().zip(expected) {
            assert!((v - e).abs() < 1e-12, "{values:?}");
        }
    }
}
