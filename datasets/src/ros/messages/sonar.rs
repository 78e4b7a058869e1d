//! Sonar beams: `echofield_msgs/SonarBeam`, Ping360 `SonarEcho` (ROS 2
//! and ROS 1), `marine_acoustic_msgs/RawSonarImage`,
//! `sensor_msgs/LaserScan`, and the Girona caves data set's
//! `RangeImageBeam`.

use super::{finite, positive};
use crate::mcap::validate::{self, FieldError};
use crate::ros::wire::WireReader;
use echofield_frontend::sensors::SonarBeam;

/// Bins of the beam rebuilt from one LaserScan ray: `range_max` is cut
/// into this many.
const LASER_SCAN_BINS: f64 = 500.0;

pub(super) fn echofield_beam<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
) -> Result<SonarBeam, FieldError> {
    let beam = SonarBeam {
        stamp_s,
        angle_rad: r.f64("angle_rad")?,
        bin_size_m: r.f64("bin_size_m")?,
        first_bin_range_m: r.f64("first_bin_range_m")?,
        intensities: r.byte_seq("intensities")?,
    };
    validate::beam(&beam)?;
    Ok(beam)
}

/// The unit of a Ping360 echo's `angle`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum AngleUnit {
    /// The ROS 2 driver (`ping360_sonar_msgs`).
    Radians,
    /// The ROS 1 driver (`ping360_sonar`): the head's gradians, 400 per turn.
    Gradians,
}

/// A Ping360 `SonarEcho` after its header: one beam of
/// `number_of_samples` bins over `[0, range]` m.
pub(super) fn ping360_echo<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
    unit: AngleUnit,
) -> Result<SonarBeam, FieldError> {
    let angle = finite("angle", f64::from(r.f32("angle")?))?;
    let angle_rad = match unit {
        AngleUnit::Radians => angle,
        AngleUnit::Gradians => angle * std::f64::consts::PI / 200.0,
    };
    r.u8("gain")?;
    let samples = r.u16("number_of_samples")?;
    r.u16("transmit_frequency")?;
    r.u16("speed_of_sound")?;
    let range_m = positive("range", f64::from(r.u8("range")?))?;
    let intensities = r.byte_seq("intensities")?;
    if intensities.is_empty() || intensities.len() != usize::from(samples) {
        return Err(FieldError::new(
            "intensities",
            format!(
                "{} intensities, but number_of_samples is {samples}",
                intensities.len()
            ),
        ));
    }
    let beam = SonarBeam {
        stamp_s,
        angle_rad,
        bin_size_m: range_m / f64::from(samples),
        first_bin_range_m: 0.0,
        intensities,
    };
    validate::beam(&beam)?;
    Ok(beam)
}

/// `SonarImageData.dtype` values read.
const DTYPE_UINT8: u32 = 0;
const DTYPE_UINT16: u32 = 2;

/// The beams of one `marine_acoustic_msgs/RawSonarImage`: one beam per
/// `rx_angles` entry, bins of `sound_speed / (2 sample_rate)` metres from
/// `sample0`, each beam stamped `stamp_s` plus its `tx_delays` entry (when
/// there is one per beam), uint16 samples scaled to their high byte.
/// Errors name the field: an unread dtype, no bins, a count of angles or
/// bytes that does not match the beams, a non-finite or non-positive value.
pub(super) fn raw_sonar_image<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
) -> Result<Vec<SonarBeam>, FieldError> {
    let image = RawImage::read(r)?;
    let bytes = image.sample_bytes()?;
    let RawImage {
        sound_speed,
        sample_rate,
        samples,
        sample0,
        tx_delays,
        rx_angles,
        big_endian,
        beam_count,
        data,
        ..
    } = image;
    let bin_size_m = sound_speed / (2.0 * sample_rate);
    let mut beams = Vec::with_capacity(beam_count);
    for (i, row) in data.chunks_exact(samples * bytes).enumerate() {
        let angle_rad = finite(&format!("rx_angles[{i}]"), f64::from(rx_angles[i]))?;
        let delay_s = match tx_delays.get(i) {
            Some(&d) if tx_delays.len() == beam_count => {
                finite(&format!("tx_delays[{i}]"), f64::from(d))?
            }
            _ => 0.0,
        };
        let beam = SonarBeam {
            stamp_s: stamp_s + delay_s,
            angle_rad,
            bin_size_m,
            first_bin_range_m: f64::from(sample0) * bin_size_m,
            intensities: eight_bit(row, bytes, big_endian),
        };
        validate::beam(&beam)?;
        beams.push(beam);
    }
    Ok(beams)
}

/// The fields of a `RawSonarImage` that make its beams, read in wire
/// order (the others are skipped).
struct RawImage {
    /// m/s, positive.
    sound_speed: f64,
    /// Hz, positive.
    sample_rate: f64,
    samples: usize,
    sample0: u32,
    tx_delays: Vec<f32>,
    rx_angles: Vec<f32>,
    big_endian: bool,
    dtype: u32,
    beam_count: usize,
    data: Vec<u8>,
}

impl RawImage {
    fn read<R: WireReader>(r: &mut R) -> Result<Self, FieldError> {
        r.f32("ping_info.frequency")?;
        let sound_speed = positive(
            "ping_info.sound_speed",
            f64::from(r.f32("ping_info.sound_speed")?),
        )?;
        r.f32_seq("ping_info.tx_beamwidths")?;
        r.f32_seq("ping_info.rx_beamwidths")?;
        let sample_rate = positive("sample_rate", f64::from(r.f32("sample_rate")?))?;
        let samples = r.u32("samples_per_beam")? as usize;
        let sample0 = r.u32("sample0")?;
        let tx_delays = r.f32_seq("tx_delays")?;
        r.f32_seq("tx_angles")?;
        let rx_angles = r.f32_seq("rx_angles")?;
        Ok(Self {
            sound_speed,
            sample_rate,
            samples,
            sample0,
            tx_delays,
            rx_angles,
            big_endian: r.bool("image.is_bigendian")?,
            dtype: r.u32("image.dtype")?,
            beam_count: r.u32("image.beam_count")? as usize,
            data: r.byte_seq("image.data")?,
        })
    }

    /// Bytes per sample (1 or 2), after checking that the image has bins
    /// and that the angles and the data match its beams.
    fn sample_bytes(&self) -> Result<usize, FieldError> {
        let (samples, beam_count) = (self.samples, self.beam_count);
        let bytes = match self.dtype {
            DTYPE_UINT8 => 1,
            DTYPE_UINT16 => 2,
            other => {
                return Err(FieldError::new(
                    "image.dtype",
                    format!("dtype {other} is not read (uint8 = 0, uint16 = 2)"),
                ));
            }
        };
        if samples == 0 || beam_count == 0 {
            return Err(FieldError::new(
                "samples_per_beam",
                format!("{samples} samples per beam in {beam_count} beams: no bins"),
            ));
        }
        if self.rx_angles.len() != beam_count {
            return Err(FieldError::new(
                "rx_angles",
                format!("{} angles for {beam_count} beams", self.rx_angles.len()),
            ));
        }
        if self.data.len() != beam_count * samples * bytes {
            return Err(FieldError::new(
                "image.data",
                format!(
                    "{} bytes, but {beam_count} beams x {samples} samples x {bytes} bytes = {}",
                    self.data.len(),
                    beam_count * samples * bytes
                ),
            ));
        }
        Ok(bytes)
    }
}

/// One beam's samples as 8-bit intensities: as they are with one byte per
/// sample, else the high byte of each uint16 (of the given endianness).
fn eight_bit(row: &[u8], bytes: usize, big_endian: bool) -> Vec<u8> {
    if bytes == 1 {
        return row.to_vec();
    }
    row.chunks_exact(2)
        .map(|b| {
            let v = if big_endian {
                u16::from_be_bytes([b[0], b[1]])
            } else {
                u16::from_le_bytes([b[0], b[1]])
            };
            (v >> 8) as u8
        })
        .collect()
}

pub(super) fn laser_scan<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
) -> Result<Vec<SonarBeam>, FieldError> {
    let angle_min = finite("angle_min", f64::from(r.f32("angle_min")?))?;
    finite("angle_max", f64::from(r.f32("angle_max")?))?;
    let increment = finite("angle_increment", f64::from(r.f32("angle_increment")?))?;
    let time_increment = finite("time_increment", f64::from(r.f32("time_increment")?))?;
    r.f32("scan_time")?;
    let range_min = finite("range_min", f64::from(r.f32("range_min")?))?;
    let range_max = positive("range_max", f64::from(r.f32("range_max")?))?;
    let ranges = r.f32_seq("ranges")?;
    let intensities = r.f32_seq("intensities")?;
    if increment == 0.0 && intensities.len() > 1 {
        // One beam whose bins are the intensities (Girona caves layout).
        let values = intensities.iter().map(|&v| f64::from(v));
        let bins = intensity_bins("intensities", values)?;
        return one_beam_over_range(stamp_s, angle_min, range_max, bins).map(|b| vec![b]);
    }
    if ranges.is_empty() {
        return Err(FieldError::new(
            "ranges",
            "no range (and no one-beam intensities)",
        ));
    }
    if !intensities.is_empty() && intensities.len() != ranges.len() {
        return Err(FieldError::new(
            "intensities",
            format!(
                "{} intensities for {} ranges",
                intensities.len(),
                ranges.len()
            ),
        ));
    }
    let bin_size_m = range_max / LASER_SCAN_BINS;
    let n_bins = LASER_SCAN_BINS as usize + 1;
    let mut beams = Vec::with_capacity(ranges.len());
    for (i, &range) in ranges.iter().enumerate() {
        let range = f64::from(range);
        let mut bins = vec![0u8; n_bins];
        // NaN, ±inf and out-of-limit values are "no return" (REP-117).
        if range.is_finite() && range > 0.0 && range >= range_min && range <= range_max {
            let bin = ((range / bin_size_m) as usize).min(n_bins - 1);
            bins[bin] = 255;
        }
        let beam = SonarBeam {
            stamp_s: stamp_s + i as f64 * time_increment,
            angle_rad: angle_min + i as f64 * increment,
            bin_size_m,
            first_bin_range_m: 0.0,
            intensities: bins,
        };
        validate::beam(&beam).map_err(|e| FieldError::new(format!("ranges[{i}]"), e.message))?;
        beams.push(beam);
    }
    Ok(beams)
}

/// Intensities given as numbers (`field[i]`) as 8-bit bins; a value
/// outside 0-255 is an error naming it.
fn intensity_bins(field: &str, values: impl Iterator<Item = f64>) -> Result<Vec<u8>, FieldError> {
    values
        .enumerate()
        .map(|(i, v)| {
            let v = finite(&format!("{field}[{i}]"), v)?;
            if !(0.0..=255.0).contains(&v) {
                return Err(FieldError::new(
                    format!("{field}[{i}]"),
                    format!("{v} is outside 0-255 (an intensity per bin)"),
                ));
            }
            Ok(v.round() as u8)
        })
        .collect()
}

/// One beam at `angle_rad` whose `bins` cut `[0, range_max_m]` evenly:
/// the Girona caves data set's layout, shared by its `RangeImageBeam` and
/// its one-beam LaserScan twins so that both give the same beam.
fn one_beam_over_range(
    stamp_s: f64,
    angle_rad: f64,
    range_max_m: f64,
    bins: Vec<u8>,
) -> Result<SonarBeam, FieldError> {
    let beam = SonarBeam {
        stamp_s,
        angle_rad,
        bin_size_m: range_max_m / bins.len() as f64,
        first_bin_range_m: 0.0,
        intensities: bins,
    };
    validate::beam(&beam)?;
    Ok(beam)
}

/// `cirs_girona_cala_viuda/RangeImageBeam` after its header:
/// `float64 angle_grad, float64 angle_rad, int32 nbins, int32 max_range
/// (m), int32[] beam_data`. The beam is at `angle_rad`; `beam_data` must
/// hold `nbins` intensities (0-255).
pub(super) fn range_image_beam<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
) -> Result<SonarBeam, FieldError> {
    // The same angle in degrees; `angle_rad` is the one read.
    r.f64("angle_grad")?;
    let angle_rad = finite("angle_rad", r.f64("angle_rad")?)?;
    let nbins = r.i32("nbins")?;
    let max_range_m = positive("max_range", f64::from(r.i32("max_range")?))?;
    let n = r.seq_len("beam_data", 4)?;
    let values = (0..n)
        .map(|i| r.i32(&format!("beam_data[{i}]")).map(f64::from))
        .collect::<Result<Vec<_>, _>>()?;
    if n == 0 || usize::try_from(nbins).ok() != Some(n) {
        return Err(FieldError::new(
            "beam_data",
            format!("{n} values, but nbins is {nbins}"),
        ));
    }
    let bins = intensity_bins("beam_data", values.into_iter())?;
    one_beam_over_range(stamp_s, angle_rad, max_range_m, bins)
}

#[cfg(test)]
mod tests {
    use super::super::test_support::{cdr_decode, header, ros1_header};
    use super::super::{Decoded, MessageType, decode};
    use super::*;
    use crate::mcap::cdr::CdrWriter;
    use crate::ros::wire::Ros1Reader;

    /// A LaserScan sweep in ROS 1 serialisation: 3 rays, the middle one
    /// without a return.
    #[test]
    fn laser_scan_sweep_in_ros1() {
        let mut d = Vec::new();
        d.extend_from_slice(&0u32.to_le_bytes()); // seq
        d.extend_from_slice(&10u32.to_le_bytes());
        d.extend_from_slice(&0u32.to_le_bytes());
        d.extend_from_slice(&5u32.to_le_bytes());
        d.extend_from_slice(b"sonar");
        for v in [0.0f32, 0.2, 0.1, 0.01, 1.0, 0.5, 10.0] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.extend_from_slice(&3u32.to_le_bytes());
        for v in [4.0f32, f32::INFINITY, 9.99] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.extend_from_slice(&0u32.to_le_bytes()); // no intensities
        let mut r = Ros1Reader::new(&d);
        let (Decoded::Beams(beams), frame) = decode(MessageType::LaserScan, &mut r, 0).unwrap()
        else {
            panic!("wrong stream");
        };
        assert_eq!(frame, "sonar");
        assert_eq!(beams.len(), 3);
        assert!((beams[2].angle_rad - 0.2).abs() < 1e-6);
        assert!((beams[2].stamp_s - 10.02).abs() < 1e-6);
        let lit = |b: &SonarBeam| b.intensities.iter().position(|&v| v == 255);
        // 4 m in 0.02 m bins: bin 200.
        assert_eq!(lit(&beams[0]), Some(200));
        assert_eq!(lit(&beams[1]), None);
        assert_eq!(lit(&beams[2]), Some(499));
    }

    #[test]
    fn ping360_bin_count_mismatch_names_the_field() {
        let mut w = CdrWriter::new();
        header(&mut w, 1, 0);
        w.f32(0.5);
        w.u8(3);
        w.u16(4); // number_of_samples
        w.u16(750);
        w.u16(1500);
        w.u8(10);
        w.bytes(&[1, 2, 3]);
        let err = cdr_decode(MessageType::Ping360SonarEcho, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "intensities");
    }

    #[test]
    fn raw_sonar_image_data_length_mismatch_names_the_field() {
        let mut w = CdrWriter::new();
        header(&mut w, 1, 0);
        // ping_info: frequency, sound_speed, no beam widths.
        w.f32(700e3);
        w.f32(1500.0);
        w.u32(0);
        w.u32(0);
        w.f32(7500.0); // sample_rate
        w.u32(4); // samples_per_beam
        w.u32(0); // sample0
        w.u32(0); // tx_delays
        w.u32(0); // tx_angles
        w.u32(1); // rx_angles
        w.f32(0.5);
        w.u8(0); // is_bigendian
        w.u32(0); // dtype uint8
        w.u32(1); // beam_count
        w.bytes(&[1, 2, 3]); // 3 bytes for 4 samples
        let err = cdr_decode(MessageType::RawSonarImage, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "image.data");
    }

    /// The ROS 1 driver's angle is in gradians: 100 grad = π/2.
    #[test]
    fn ros1_ping360_angle_is_gradians() {
        let mut d = Vec::new();
        ros1_header(&mut d, 5, "sonar_frame");
        d.extend_from_slice(&100f32.to_le_bytes());
        d.push(0); // gain
        for v in [2u16, 750, 1500] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.push(4); // range, m
        d.extend_from_slice(&2u32.to_le_bytes());
        d.extend_from_slice(&[9, 8]);
        let (Decoded::Beams(beams), _) = decode(
            MessageType::Ping360SonarEchoRos1,
            &mut Ros1Reader::new(&d),
            0,
        )
        .unwrap() else {
            panic!("wrong stream");
        };
        assert!((beams[0].angle_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(
            (beams[0].bin_size_m, beams[0].intensities.clone()),
            (2.0, vec![9, 8])
        );
    }

    /// A RangeImageBeam (ROS 1) with `beam_data` of the given values.
    fn range_image_beam_ros1(nbins: i32, data: &[i32]) -> Vec<u8> {
        let mut d = Vec::new();
        ros1_header(&mut d, 7, "micron");
        d.extend_from_slice(&45f64.to_le_bytes());
        d.extend_from_slice(&std::f64::consts::FRAC_PI_4.to_le_bytes());
        d.extend_from_slice(&nbins.to_le_bytes());
        d.extend_from_slice(&20i32.to_le_bytes());
        d.extend_from_slice(&(data.len() as u32).to_le_bytes());
        for v in data {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d
    }

    #[test]
    fn range_image_beam_bins_cover_max_range() {
        let d = range_image_beam_ros1(4, &[0, 50, 191, 7]);
        let (Decoded::Beams(beams), frame) = decode(
            MessageType::GironaRangeImageBeam,
            &mut Ros1Reader::new(&d),
            0,
        )
        .unwrap() else {
            panic!("wrong stream");
        };
        assert_eq!(frame, "micron");
        let b = &beams[0];
        assert!((b.angle_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
        assert_eq!((b.bin_size_m, b.first_bin_range_m), (5.0, 0.0));
        assert_eq!(b.intensities, [0, 50, 191, 7]);
    }

    #[test]
    fn range_image_beam_errors_name_the_field() {
        let err = |d: Vec<u8>| {
            decode(
                MessageType::GironaRangeImageBeam,
                &mut Ros1Reader::new(&d),
                0,
            )
            .unwrap_err()
        };
        assert_eq!(
            err(range_image_beam_ros1(5, &[0, 50, 191, 7])).field,
            "beam_data"
        );
        assert_eq!(
            err(range_image_beam_ros1(2, &[0, 300])).field,
            "beam_data[1]"
        );
        let mut truncated = range_image_beam_ros1(4, &[0, 50, 191, 7]);
        truncated.truncate(truncated.len() - 2);
        assert_eq!(err(truncated).field, "beam_data");
    }
}
