//! `miniking_ros/AcousticBeam` in ROS 1 serialization (little-endian):
//! `std_msgs/Header` (u32 seq, u32 sec, u32 nsec, string frame_id), float32
//! range_max (m), int32 bins, float32 angle (degrees), uint8[] intensities
//! (u32 length + bytes). A string is a u32 length and the bytes.

/// ROS type name of the message.
pub const ACOUSTIC_BEAM_TYPE: &str = "miniking_ros/AcousticBeam";
/// MD5 of the message definition recorded in the committed bags.
pub const ACOUSTIC_BEAM_MD5: &str = "8500cd97501a86f9b35f0c89c7f66259";

/// A decoded beam message.
#[derive(Clone, Debug, PartialEq)]
pub struct AcousticBeam {
    pub seq: u32,
    /// `header.stamp` in seconds (0 when the driver left it unset).
    pub stamp_s: f64,
    pub frame_id: String,
    pub range_max_m: f32,
    pub bins: i32,
    pub angle_deg: f32,
    pub intensities: Vec<u8>,
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, field: &str) -> Result<&'a [u8], (String, String)> {
        let slice = self.bytes.get(self.pos..self.pos + n).ok_or_else(|| {
            let left = self.bytes.len() - self.pos;
            (field.to_string(), format!("needs {n} bytes, {left} left"))
        })?;
        self.pos += n;
        Ok(slice)
    }

    fn u32(&mut self, field: &str) -> Result<u32, (String, String)> {
        let b = self.take(4, field)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

/// Decodes one message; `Err((field, message))` names the bad field.
pub fn decode_acoustic_beam(bytes: &[u8]) -> Result<AcousticBeam, (String, String)> {
    let mut r = Reader { bytes, pos: 0 };
    let seq = r.u32("header.seq")?;
    let sec = r.u32("header.stamp.sec")?;
    let nsec = r.u32("header.stamp.nsec")?;
    let frame_len = r.u32("header.frame_id")? as usize;
    let frame_id = String::from_utf8_lossy(r.take(frame_len, "header.frame_id")?).into_owned();
    let range_max_m = f32::from_bits(r.u32("range_max")?);
    let bins = r.u32("bins")? as i32;
    let angle_deg = f32::from_bits(r.u32("angle")?);
    let count = r.u32("intensities")? as usize;
    let intensities = r.take(count, "intensities")?.to_vec();
    let bad = |field: &str, message: String| Err((field.to_string(), message));
    if r.pos != bytes.len() {
        return bad(
            "intensities",
            format!("{} bytes after the message", bytes.len() - r.pos),
        );
    }
    if !(range_max_m.is_finite() && range_max_m > 0.0) {
        return bad(
            "range_max",
            format!("{range_max_m} is not a positive range"),
        );
    }
    if bins <= 0 || bins as usize != intensities.len() {
        return bad(
            "bins",
            format!("{bins} but {} intensities", intensities.len()),
        );
    }
    if !angle_deg.is_finite() {
        return bad("angle", format!("{angle_deg} is not finite"));
    }
    Ok(AcousticBeam {
        seq,
        stamp_s: f64::from(sec) + 1e-9 * f64::from(nsec),
        frame_id,
        range_max_m,
        bins,
        angle_deg,
        intensities,
    })
}

/// Serializes a beam (for tests of this reader and its users).
pub fn encode_acoustic_beam(beam: &AcousticBeam) -> Vec<u8> {
    let mut out = Vec::new();
    let sec = beam.stamp_s.floor();
    let nsec = ((beam.stamp_s - sec) * 1e9).round();
    out.extend_from_slice(&beam.seq.to_le_bytes());
    out.extend_from_slice(&(sec as u32).to_le_bytes());
    out.extend_from_slice(&(nsec as u32).to_le_bytes());
    out.extend_from_slice(&(beam.frame_id.len() as u32).to_le_bytes());
    out.extend_from_slice(beam.frame_id.as_bytes());
    out.extend_from_slice(&beam.range_max_m.to_le_bytes());
    out.extend_from_slice(&beam.bins.to_le_bytes());
    out.extend_from_slice(&beam.angle_deg.to_le_bytes());
    out.extend_from_slice(&(beam.intensities.len() as u32).to_le_bytes());
    out.extend_from_slice(&beam.intensities);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn beam() -> AcousticBeam {
        AcousticBeam {
            seq: 7,
            stamp_s: 1432633085.5,
            frame_id: "sonar".into(),
            range_max_m: 30.0,
            bins: 4,
            angle_deg: 126.9,
            intensities: vec![1, 2, 3, 4],
        }
    }

    #[test]
    fn round_trip() {
        assert_eq!(
            decode_acoustic_beam(&encode_acoustic_beam(&beam())),
            Ok(beam())
        );
    }

    #[test]
    fn inconsistent_fields_are_named() {
        let mut b = beam();
        b.bins = 5;
        assert_eq!(
            decode_acoustic_beam(&encode_acoustic_beam(&b))
                .unwrap_err()
                .0,
            "bins"
        );
        let mut b = beam();
        b.range_max_m = f32::NAN;
        assert_eq!(
            decode_acoustic_beam(&encode_acoustic_beam(&b))
                .unwrap_err()
                .0,
            "range_max"
        );
        let bytes = encode_acoustic_beam(&beam());
        let err = decode_acoustic_beam(&bytes[..bytes.len() - 1]).unwrap_err();
        assert_eq!(err.0, "intensities");
        assert!(err.1.contains("needs 4 bytes, 3 left"), "{}", err.1);
    }
}
