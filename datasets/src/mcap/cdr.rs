//! A small reader and writer of OMG CDR (XCDR1), the message encoding of
//! ROS 2 (`cdr` in MCAP).
//!
//! A payload starts with a 4-byte encapsulation header: representation id
//! `00 01` (CDR, little-endian) or `00 00` (CDR, big-endian) and two option
//! bytes. Primitives are aligned to their own size, counted from the end of
//! that header; strings are a `u32` length that includes the NUL terminator,
//! the bytes and the NUL; sequences are a `u32` count then the elements;
//! fixed arrays have no count.
//!
//! Hand-written rather than the `cdr` crate (0.2) because (1) every read
//! here is given the field name, so an error says `orientation.w: need 8 bytes
//! at offset 60, 4 left` instead of an anonymous "unexpected EOF"; (2) the
//! `cdr` crate allocates a string or sequence of the length read from the
//! payload before checking that the payload holds it (a corrupt length asks
//! for up to 4 GiB), while this reader checks lengths against the remaining
//! bytes first; (3) `uint8[]` is copied as one slice instead of one serde call
//! per byte.

use super::validate::FieldError;

/// Representation ids of the encapsulation header.
const CDR_BE: [u8; 2] = [0x00, 0x00];
const CDR_LE: [u8; 2] = [0x00, 0x01];

/// Reads CDR primitives from one message payload.
pub struct CdrReader<'a> {
    /// The payload after the encapsulation header.
    body: &'a [u8],
    pos: usize,
    little_endian: bool,
}

impl<'a> CdrReader<'a> {
    /// Checks the encapsulation header; only plain CDR (XCDR1) is supported.
    pub fn new(payload: &'a [u8]) -> Result<Self, FieldError> {
        if payload.len() < 4 {
            return Err(FieldError::new(
                "(encapsulation)",
                format!(
                    "payload of {} bytes has no 4-byte CDR header",
                    payload.len()
                ),
            ));
        }
        let little_endian = match [payload[0], payload[1]] {
            CDR_LE => true,
            CDR_BE => false,
            other => {
                return Err(FieldError::new(
                    "(encapsulation)",
                    format!(
                        "representation id {:02x}{:02x} is not plain CDR (00 00 or 00 01)",
                        other[0], other[1]
                    ),
                ));
            }
        };
        Ok(Self {
            body: &payload[4..],
            pos: 0,
            little_endian,
        })
    }

    /// Bytes left after the current position.
    pub fn remaining(&self) -> usize {
        self.body.len() - self.pos
    }

    fn take(&mut self, field: &str, align: usize, n: usize) -> Result<&'a [u8], FieldError> {
        crate::ros::wire::take(self.body, &mut self.pos, field, align, n)
    }

    fn array<const N: usize>(&mut self, field: &str) -> Result<[u8; N], FieldError> {
        let bytes = self.take(field, N, N)?;
        let mut out: [u8; N] = bytes.try_into().expect("take returns N bytes");
        if self.little_endian != cfg!(target_endian = "little") {
            out.reverse();
        }
        Ok(out)
    }

    pub fn u8(&mut self, field: &str) -> Result<u8, FieldError> {
        Ok(self.take(field, 1, 1)?[0])
    }

    pub fn u16(&mut self, field: &str) -> Result<u16, FieldError> {
        Ok(u16::from_ne_bytes(self.array(field)?))
    }

    pub fn i64(&mut self, field: &str) -> Result<i64, FieldError> {
        Ok(i64::from_ne_bytes(self.array(field)?))
    }

    pub fn f32(&mut self, field: &str) -> Result<f32, FieldError> {
        Ok(f32::from_ne_bytes(self.array(field)?))
    }

    pub fn u32(&mut self, field: &str) -> Result<u32, FieldError> {
        Ok(u32::from_ne_bytes(self.array(field)?))
    }

    pub fn i32(&mut self, field: &str) -> Result<i32, FieldError> {
        Ok(i32::from_ne_bytes(self.array(field)?))
    }

    pub fn f64(&mut self, field: &str) -> Result<f64, FieldError> {
        Ok(f64::from_ne_bytes(self.array(field)?))
    }

    /// A `string`: length (with the NUL) checked against the payload before
    /// anything is allocated.
    pub fn string(&mut self, field: &str) -> Result<String, FieldError> {
        let len = self.u32(field)? as usize;
        if len == 0 {
            // Some writers encode "" as length 0 without a terminator.
            return Ok(String::new());
        }
        let bytes = self.take(field, 1, len)?;
        let (last, text) = bytes.split_last().expect("len > 0");
        if *last != 0 {
            return Err(FieldError::new(field, "string is not NUL-terminated"));
        }
        String::from_utf8(text.to_vec())
            .map_err(|e| FieldError::new(field, format!("string is not UTF-8: {e}")))
    }

    /// A `uint8[]` sequence.
    pub fn bytes(&mut self, field: &str) -> Result<&'a [u8], FieldError> {
        let len = self.u32(field)? as usize;
        self.take(field, 1, len)
    }
}

/// Writes CDR (little-endian) payloads, encapsulation header included.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    pub fn new() -> Self {
        Self {
            buf: vec![CDR_LE[0], CDR_LE[1], 0, 0],
        }
    }

    fn align(&mut self, n: usize) {
        let body_len = self.buf.len() - 4;
        let padded = body_len.next_multiple_of(n);
        self.buf.resize(padded + 4, 0);
    }

    #[cfg(test)]
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    #[cfg(test)]
    pub fn u16(&mut self, v: u16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    #[cfg(test)]
    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f64_array(&mut self, values: &[f64]) {
        for v in values {
            self.f64(*v);
        }
    }

    /// Panics if the string is longer than 4 GiB (never the case for frame ids).
    pub fn string(&mut self, s: &str) {
        let len = u32::try_from(s.len() + 1).expect("CDR string shorter than 4 GiB");
        self.u32(len);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// Panics if the sequence is longer than 4 GiB.
    pub fn bytes(&mut self, data: &[u8]) {
        let len = u32::try_from(data.len()).expect("CDR sequence shorter than 4 GiB");
        self.u32(len);
        self.buf.extend_from_slice(data);
    }

    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_matches_the_cdr_rules() {
        let mut w = CdrWriter::new();
        w.u8(7);
        w.f64(1.0); // aligned to 8 from the end of the header: 7 padding bytes
        w.string("ab");
        w.bytes(&[1, 2, 3]);
        w.u32(9); // 24 + 3 bytes so far -> one padding byte
        let bytes = w.into_bytes();
        let mut expected = vec![0, 1, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0];
        expected.extend_from_slice(&1.0f64.to_le_bytes());
        expected.extend_from_slice(&[3, 0, 0, 0, b'a', b'b', 0]);
        expected.extend_from_slice(&[0]); // align 4 for the sequence length
        expected.extend_from_slice(&[3, 0, 0, 0, 1, 2, 3]);
        expected.extend_from_slice(&[0]); // align 4
        expected.extend_from_slice(&[9, 0, 0, 0]);
        assert_eq!(bytes, expected);

        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(r.u8("a").unwrap(), 7);
        assert_eq!(r.f64("b").unwrap(), 1.0);
        assert_eq!(r.string("c").unwrap(), "ab");
        assert_eq!(r.bytes("d").unwrap(), &[1, 2, 3]);
        assert_eq!(r.u32("e").unwrap(), 9);
        assert_eq!(r.remaining(), 0);
    }

    #[test]
    fn big_endian_payload() {
        let mut bytes = vec![0, 0, 0, 0];
        bytes.extend_from_slice(&(-5i32).to_be_bytes());
        bytes.extend_from_slice(&[0; 4]);
        bytes.extend_from_slice(&2.5f64.to_be_bytes());
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(r.i32("sec").unwrap(), -5);
        assert_eq!(r.f64("x").unwrap(), 2.5);
    }

    #[test]
    fn huge_length_is_an_error_not_an_allocation() {
        let mut bytes = vec![0, 1, 0, 0];
        bytes.extend_from_slice(&u32::MAX.to_le_bytes());
        let err = CdrReader::new(&bytes)
            .unwrap()
            .bytes("intensities")
            .unwrap_err();
        assert_eq!(err.field, "intensities");
        assert!(err.message.contains("truncated"), "{}", err.message);
    }

    #[test]
    fn unsupported_representation() {
        let err = CdrReader::new(&[0, 3, 0, 0]).err().unwrap();
        assert_eq!(err.field, "(encapsulation)");
    }
}
