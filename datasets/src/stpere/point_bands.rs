//! The compact form of the St Pere point sets kept in
//! `datasets/stpere-marina-sonar/bands.csv`, and its expansion back to the
//! PCD files that [`super::keyframes::read_keyframes`] reads.
//!
//! `bands.csv` has the header `keyframe,angle_index,first_bin,last_bin`:
//! every point of `pclKeyFrameK.pcd` lies on beam `angle_index` (angle
//! `angle_index · step`) at the far end of a 1-based bin (range
//! `bin · bin_size`), and the points of one beam in consecutive bins are
//! one row (`first_bin..=last_bin`). Expanding the rows gives back the
//! files' point sets exactly (the rows were written by
//! `datasets/stpere-marina-sonar/make_bands.py`).

use super::keyframes::KEYFRAME_CSV;
use super::sonar::SonarSetup;
use crate::error::DatasetError;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

/// One row of `bands.csv`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
pub struct PointBand {
    pub keyframe: u64,
    pub angle_index: u32,
    pub first_bin: u32,
    pub last_bin: u32,
}

/// Reads `bands.csv`; errors name the line and the field.
pub fn read_point_bands(path: &Path) -> Result<Vec<PointBand>, DatasetError> {
    let file = std::fs::File::open(path).map_err(|e| DatasetError::io(path, e))?;
    let mut reader = csv::Reader::from_reader(file);
    let mut bands = Vec::new();
    for record in reader.records() {
        let error = |line: u64, field: &str, message: String| {
            DatasetError::parse(path, format!("line {line}"), field, message)
        };
        let record = record
            .map_err(|e| error(e.position().map_or(0, |p| p.line()), "row", e.to_string()))?;
        let line = record.position().map_or(0, |p| p.line());
        let band: PointBand = record
            .deserialize(None)
            .map_err(|e| error(line, "row", e.to_string()))?;
        if band.first_bin == 0 || band.last_bin < band.first_bin {
            return Err(error(
                line,
                "first_bin, last_bin",
                format!(
                    "{}..={} is not a range of 1-based bins",
                    band.first_bin, band.last_bin
                ),
            ));
        }
        bands.push(band);
    }
    Ok(bands)
}

/// Writes `out_dir/pclKeyFrameK.pcd` for every key frame of `bands_csv`
/// and copies `keyframes_csv` beside them: a folder that
/// [`super::keyframes::read_keyframes`] reads. Points are written like
/// the published files (ASCII, 4 decimals, `z = 0`).
pub fn expand_point_bands(
    bands_csv: &Path,
    keyframes_csv: &Path,
    setup: &SonarSetup,
    out_dir: &Path,
) -> Result<usize, DatasetError> {
    let bands = read_point_bands(bands_csv)?;
    let mut frames: BTreeMap<u64, Vec<(f64, f64)>> = BTreeMap::new();
    for band in &bands {
        let angle = f64::from(band.angle_index) * setup.step_rad;
        let points = frames.entry(band.keyframe).or_default();
        for bin in band.first_bin..=band.last_bin {
            let range = f64::from(bin) * setup.bin_size_m;
            points.push((range * angle.cos(), range * angle.sin()));
        }
    }
    std::fs::create_dir_all(out_dir).map_err(|e| DatasetError::io(out_dir, e))?;
    let csv_out = out_dir.join(KEYFRAME_CSV);
    std::fs::copy(keyframes_csv, &csv_out).map_err(|e| DatasetError::io(&csv_out, e))?;
    let mut total = 0;
    for (keyframe, points) in &frames {
        let path = out_dir.join(format!("pclKeyFrame{keyframe}.pcd"));
        let mut text = Vec::with_capacity(points.len() * 24 + 256);
        let n = points.len();
        write!(
            text,
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\n\
             HEIGHT 1\nVIEWPOINT 0.0 0.0 0.0 1.0 0.0 0.0 0.0\nPOINTS {n}\nDATA ascii\n"
        )
        .expect("writing to memory");
        for (x, y) in points {
            writeln!(text, "{x:.4} {y:.4} 0.0000 ").expect("writing to memory");
        }
        std::fs::write(&path, text).map_err(|e| DatasetError::io(&path, e))?;
        total += n;
    }
    Ok(total)
}

/// The sonar setup of the St Pere mission (`_SETUP.log`: 50 m, 500 bins
/// of 0.1 m, 200 steps of 0.0314159 rad), which `bands.csv` is indexed by.
pub const ST_PERE_SETUP: SonarSetup = SonarSetup {
    range_m: 50.0,
    bin_size_m: 0.1,
    step_rad: 0.0314159,
};

/// The repository's committed St Pere point sets
/// (`datasets/stpere-marina-sonar`, rotations 1-115) expanded into
/// `out_dir/keyframes`; returns that folder, ready for
/// [`super::read_stpere_with_keyframes`] or `--keyframes`.
pub fn committed_keyframes(out_dir: &Path) -> Result<std::path::PathBuf, DatasetError> {
    let sonar = Path::new(env!("CARGO_MANIFEST_DIR")).join("stpere-marina-sonar");
    let keyframes = out_dir.join("keyframes");
    expand_point_bands(
        &sonar.join("bands.csv"),
        &sonar.join(KEYFRAME_CSV),
        &ST_PERE_SETUP,
        &keyframes,
    )?;
    Ok(keyframes)
}
