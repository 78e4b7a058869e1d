//! The two serialisations of ROS messages behind one field reader, so that
//! each message's mapping to echofield records ([`super::messages`]) is
//! written once.
//!
//! - ROS 2: OMG CDR (XCDR1), [`CdrReader`]: primitives aligned to their
//!   size, strings NUL-terminated, `builtin_interfaces/Time` is
//!   `int32 sec, uint32 nanosec`, `std_msgs/Header` has no `seq`.
//! - ROS 1: the ROS 1 wire format, [`Ros1Reader`]: little-endian, packed
//!   (no alignment), strings `u32` length + bytes without a terminator,
//!   variable arrays `u32` count + elements, fixed arrays no count,
//!   `time` is `uint32 secs, uint32 nsecs`, `std_msgs/Header` starts with
//!   `uint32 seq`.
//!
//! Every read names its field, so a bad message gives an error naming the
//! field; lengths read from the payload are checked against the bytes left
//! before anything is allocated.

use crate::mcap::cdr::CdrReader;
use crate::mcap::validate::FieldError;

/// The stamp and frame of a `std_msgs/Header`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Header {
    /// Seconds of the stamp (ROS 1: unsigned, ROS 2: signed).
    pub sec: i64,
    pub nanosec: u32,
    pub frame_id: String,
}

/// Reads the fields of one serialised ROS message in order.
pub(crate) trait WireReader {
    fn u8(&mut self, field: &str) -> Result<u8, FieldError>;
    fn u16(&mut self, field: &str) -> Result<u16, FieldError>;
    fn u32(&mut self, field: &str) -> Result<u32, FieldError>;
    fn i32(&mut self, field: &str) -> Result<i32, FieldError>;
    fn i64(&mut self, field: &str) -> Result<i64, FieldError>;
    fn f32(&mut self, field: &str) -> Result<f32, FieldError>;
    fn f64(&mut self, field: &str) -> Result<f64, FieldError>;
    fn string(&mut self, field: &str) -> Result<String, FieldError>;
    /// A `uint8[]` sequence.
    fn byte_seq(&mut self, field: &str) -> Result<Vec<u8>, FieldError>;
    /// Bytes left after the current position.
    fn remaining(&self) -> usize;
    /// A time stamp (`time` in ROS 1, `builtin_interfaces/Time` in ROS 2).
    fn time(&mut self, field: &str) -> Result<(i64, u32), FieldError>;
    /// `std_msgs/Header`; `prefix` names it in errors (`header`,
    /// `transforms[2].header`).
    fn header(&mut self, prefix: &str) -> Result<Header, FieldError>;

    /// The element count of a variable-length array (`u32` in both
    /// formats), checked against the bytes left (each element takes at
    /// least `min_element_bytes`) before anything is allocated.
    fn seq_len(&mut self, field: &str, min_element_bytes: usize) -> Result<usize, FieldError> {
        let n = self.u32(field)? as usize;
        if n.saturating_mul(min_element_bytes) > self.remaining() {
            return Err(FieldError::new(
                field,
                format!(
                    "truncated: {n} elements of at least {min_element_bytes} bytes, {} bytes left",
                    self.remaining()
                ),
            ));
        }
        Ok(n)
    }

    fn bool(&mut self, field: &str) -> Result<bool, FieldError> {
        Ok(self.u8(field)? != 0)
    }

    /// A `float32[]` sequence.
    fn f32_seq(&mut self, field: &str) -> Result<Vec<f32>, FieldError> {
        let n = self.seq_len(field, 4)?;
        (0..n).map(|i| self.f32(&format!("{field}[{i}]"))).collect()
    }

    /// A `float64[N]` fixed array.
    fn f64_array<const N: usize>(&mut self, field: &str) -> Result<[f64; N], FieldError> {
        let mut out = [0.0; N];
        for (i, v) in out.iter_mut().enumerate() {
            *v = self.f64(&format!("{field}[{i}]"))?;
        }
        Ok(out)
    }
}

/// The next `n` bytes of `data` from `*pos` rounded up to a multiple of
/// `align` (CDR aligns primitives to their size; ROS 1 is packed: 1),
/// advancing `*pos` past them; too few bytes left is an error naming
/// `field`. Both readers take every byte through here.
pub(crate) fn take<'a>(
    data: &'a [u8],
    pos: &mut usize,
    field: &str,
    align: usize,
    n: usize,
) -> Result<&'a [u8], FieldError> {
    let start = pos.next_multiple_of(align);
    let Some(end) = start.checked_add(n).filter(|&e| e <= data.len()) else {
        return Err(FieldError::new(
            field,
            format!(
                "truncated: need {n} bytes at offset {start}, {} left",
                data.len().saturating_sub(start)
            ),
        ));
    };
    *pos = end;
    Ok(&data[start..end])
}

/// Checks a nanosecond count and returns the header.
fn header_from(
    prefix: &str,
    sec: i64,
    nanosec: u32,
    frame_id: String,
) -> Result<Header, FieldError> {
    if nanosec >= 1_000_000_000 {
        return Err(FieldError::new(
            format!("{prefix}.stamp.nanosec"),
            format!("{nanosec} is not below 10^9"),
        ));
    }
    Ok(Header {
        sec,
        nanosec,
        frame_id,
    })
}

impl WireReader for CdrReader<'_> {
    fn u8(&mut self, field: &str) -> Result<u8, FieldError> {
        CdrReader::u8(self, field)
    }
    fn u16(&mut self, field: &str) -> Result<u16, FieldError> {
        CdrReader::u16(self, field)
    }
    fn u32(&mut self, field: &str) -> Result<u32, FieldError> {
        CdrReader::u32(self, field)
    }
    fn i32(&mut self, field: &str) -> Result<i32, FieldError> {
        CdrReader::i32(self, field)
    }
    fn i64(&mut self, field: &str) -> Result<i64, FieldError> {
        CdrReader::i64(self, field)
    }
    fn remaining(&self) -> usize {
        CdrReader::remaining(self)
    }
    fn f32(&mut self, field: &str) -> Result<f32, FieldError> {
        CdrReader::f32(self, field)
    }
    fn f64(&mut self, field: &str) -> Result<f64, FieldError> {
        CdrReader::f64(self, field)
    }
    fn string(&mut self, field: &str) -> Result<String, FieldError> {
        CdrReader::string(self, field)
    }
    fn byte_seq(&mut self, field: &str) -> Result<Vec<u8>, FieldError> {
        CdrReader::bytes(self, field).map(<[u8]>::to_vec)
    }
    fn time(&mut self, field: &str) -> Result<(i64, u32), FieldError> {
        let sec = CdrReader::i32(self, &format!("{field}.sec"))?;
        let nanosec = CdrReader::u32(self, &format!("{field}.nanosec"))?;
        Ok((i64::from(sec), nanosec))
    }
    fn header(&mut self, prefix: &str) -> Result<Header, FieldError> {
        let (sec, nanosec) = self.time(&format!("{prefix}.stamp"))?;
        let frame_id = CdrReader::string(self, &format!("{prefix}.frame_id"))?;
        header_from(prefix, sec, nanosec, frame_id)
    }
}

/// Reads a ROS 1 serialised message (the `data` of a bag's message record).
pub(crate) struct Ros1Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Ros1Reader<'a> {
    pub fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    fn take(&mut self, field: &str, n: usize) -> Result<&'a [u8], FieldError> {
        take(self.data, &mut self.pos, field, 1, n)
    }

    fn array<const N: usize>(&mut self, field: &str) -> Result<[u8; N], FieldError> {
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(field, N)?);
        Ok(out)
    }
}

impl WireReader for Ros1Reader<'_> {
    fn u8(&mut self, field: &str) -> Result<u8, FieldError> {
        Ok(self.take(field, 1)?[0])
    }
    fn u16(&mut self, field: &str) -> Result<u16, FieldError> {
        Ok(u16::from_le_bytes(self.array(field)?))
    }
    fn u32(&mut self, field: &str) -> Result<u32, FieldError> {
        Ok(u32::from_le_bytes(self.array(field)?))
    }
    fn i32(&mut self, field: &str) -> Result<i32, FieldError> {
        Ok(i32::from_le_bytes(self.array(field)?))
    }
    fn i64(&mut self, field: &str) -> Result<i64, FieldError> {
        Ok(i64::from_le_bytes(self.array(field)?))
    }
    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
    fn f32(&mut self, field: &str) -> Result<f32, FieldError> {
        Ok(f32::from_le_bytes(self.array(field)?))
    }
    fn f64(&mut self, field: &str) -> Result<f64, FieldError> {
        Ok(f64::from_le_bytes(self.array(field)?))
    }
    fn string(&mut self, field: &str) -> Result<String, FieldError> {
        let bytes = self.byte_seq(field)?;
        String::from_utf8(bytes)
            .map_err(|e| FieldError::new(field, format!("string is not UTF-8: {e}")))
    }
    fn byte_seq(&mut self, field: &str) -> Result<Vec<u8>, FieldError> {
        let n = self.u32(field)? as usize;
        self.take(field, n).map(<[u8]>::to_vec)
    }
    fn time(&mut self, field: &str) -> Result<(i64, u32), FieldError> {
        let sec = self.u32(&format!("{field}.secs"))?;
        let nanosec = self.u32(&format!("{field}.nsecs"))?;
        Ok((i64::from(sec), nanosec))
    }
    fn header(&mut self, prefix: &str) -> Result<Header, FieldError> {
        self.u32(&format!("{prefix}.seq"))?;
        let (sec, nanosec) = self.time(&format!("{prefix}.stamp"))?;
        let frame_id = self.string(&format!("{prefix}.frame_id"))?;
        header_from(prefix, sec, nanosec, frame_id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros1_layout_is_packed_little_endian() {
        let mut data = Vec::new();
        data.extend_from_slice(&7u32.to_le_bytes()); // seq
        data.extend_from_slice(&100u32.to_le_bytes());
        data.extend_from_slice(&5u32.to_le_bytes());
        data.extend_from_slice(&2u32.to_le_bytes());
        data.extend_from_slice(b"ab");
        data.push(9); // u8, then an unaligned f64
        data.extend_from_slice(&1.5f64.to_le_bytes());
        let mut r = Ros1Reader::new(&data);
        let h = r.header("header").unwrap();
        assert_eq!((h.sec, h.nanosec, h.frame_id.as_str()), (100, 5, "ab"));
        assert_eq!(WireReader::u8(&mut r, "g").unwrap(), 9);
        assert_eq!(WireReader::f64(&mut r, "x").unwrap(), 1.5);
        assert_eq!(r.remaining(), 0);
        let err = WireReader::u32(&mut r, "more").unwrap_err();
        assert_eq!(err.field, "more");
    }

    #[test]
    fn huge_sequence_count_is_an_error_not_an_allocation() {
        let data = u32::MAX.to_le_bytes();
        let err = Ros1Reader::new(&data).f32_seq("ranges").unwrap_err();
        assert_eq!(err.field, "ranges");
        let mut cdr = vec![0, 1, 0, 0];
        cdr.extend_from_slice(&u32::MAX.to_le_bytes());
        let err = CdrReader::new(&cdr).unwrap().f32_seq("ranges").unwrap_err();
        assert!(err.message.contains("truncated"), "{}", err.message);
    }
}
