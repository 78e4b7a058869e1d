//! Blue Robotics Ping protocol framing and the Ping360 `device_data` message.
//!
//! Message: `"BR"`, u16 payload length, u16 message id, u8 source id, u8
//! destination id, payload, u16 checksum = sum of every preceding byte of the
//! message (mod 2^16); all little-endian. The serial stream may hold noise and
//! damaged messages: after a bad checksum the parser resynchronises on the
//! next `"BR"`.

use std::ops::Range;

const HEADER_BYTES: usize = 8;
const CHECKSUM_BYTES: usize = 2;
/// Message id of Ping360 `device_data`.
pub const DEVICE_DATA_ID: u16 = 2300;
/// Ping360 angles: 400 gradians per turn.
pub const GRADIANS_PER_TURN: f64 = 400.0;
/// Duration of one sample-period tick, seconds.
pub const SAMPLE_PERIOD_TICK_S: f64 = 25e-9;
/// Speed of sound Ping Viewer assumes, m/s.
pub const SPEED_OF_SOUND_MPS: f64 = 1500.0;

/// One message with a good checksum.
pub(crate) struct Message {
    pub id: u16,
    /// Payload bytes in the stream.
    pub payload: Range<usize>,
}

/// All messages of a stream and what was thrown away.
pub(crate) struct Framing {
    pub messages: Vec<Message>,
    pub bad_checksums: usize,
    pub skipped_bytes: usize,
    pub truncated_tail_bytes: usize,
}

pub(crate) fn parse_messages(stream: &[u8]) -> Framing {
    let mut framing = Framing {
        messages: Vec::new(),
        bad_checksums: 0,
        skipped_bytes: 0,
        truncated_tail_bytes: 0,
    };
    let mut consumed = 0usize;
    // Start of a message that runs past the end of the stream; cleared when a
    // good message follows (then it was a false "BR" in noise).
    let mut incomplete_from: Option<usize> = None;
    let mut i = 0usize;
    while i + 1 < stream.len() {
        if stream[i] != b'B' || stream[i + 1] != b'R' {
            i += 1;
            continue;
        }
        if i + HEADER_BYTES > stream.len() {
            incomplete_from.get_or_insert(i);
            break;
        }
        let payload_len = usize::from(u16::from_le_bytes([stream[i + 2], stream[i + 3]]));
        let checksum_at = i + HEADER_BYTES + payload_len;
        if checksum_at + CHECKSUM_BYTES > stream.len() {
            incomplete_from.get_or_insert(i);
            i += 1;
            continue;
        }
        let sum = stream[i..checksum_at]
            .iter()
            .fold(0u16, |acc, &b| acc.wrapping_add(u16::from(b)));
        let expected = u16::from_le_bytes([stream[checksum_at], stream[checksum_at + 1]]);
        if sum != expected {
            framing.bad_checksums += 1;
            i += 1;
            continue;
        }
        framing.messages.push(Message {
            id: u16::from_le_bytes([stream[i + 4], stream[i + 5]]),
            payload: i + HEADER_BYTES..checksum_at,
        });
        consumed += checksum_at + CHECKSUM_BYTES - i;
        incomplete_from = None;
        i = checksum_at + CHECKSUM_BYTES;
    }
    framing.truncated_tail_bytes = incomplete_from.map_or(0, |start| stream.len() - start);
    framing.skipped_bytes = stream.len() - consumed - framing.truncated_tail_bytes;
    framing
}

/// The fields of a Ping360 `device_data` payload.
#[derive(Debug, PartialEq)]
pub(crate) struct DeviceData<'a> {
    /// Receiver gain setting: 0 low, 1 normal, 2 high.
    pub gain_setting: u8,
    pub angle_grad: u16,
    /// Length of the transmitted pulse, microseconds.
    pub transmit_duration_us: u16,
    pub sample_period_ticks: u16,
    /// Transmit frequency, kHz.
    pub transmit_frequency_khz: u16,
    pub data: &'a [u8],
}

impl DeviceData<'_> {
    /// Range length of one sample: half the sound travel during one period.
    pub fn bin_size_m(&self) -> f64 {
        0.5 * SPEED_OF_SOUND_MPS * f64::from(self.sample_period_ticks) * SAMPLE_PERIOD_TICK_S
    }
}

/// Payload: u8 mode, u8 gain, u16 angle (grad), u16 transmit duration (µs),
/// u16 sample period (25 ns ticks), u16 transmit frequency (kHz), u16 number
/// of samples, u16 data length, data.
pub(crate) fn decode_device_data(payload: &[u8]) -> Result<DeviceData<'_>, String> {
    const FIXED: usize = 14;
    if payload.len() < FIXED {
        return Err(format!(
            "payload of {} bytes, the fixed part needs {FIXED}",
            payload.len()
        ));
    }
    let u16_at = |k: usize| u16::from_le_bytes([payload[k], payload[k + 1]]);
    let gain_setting = payload[1];
    let angle_grad = u16_at(2);
    let transmit_duration_us = u16_at(4);
    let sample_period_ticks = u16_at(6);
    let transmit_frequency_khz = u16_at(8);
    let samples = usize::from(u16_at(10));
    let data_length = usize::from(u16_at(12));
    let data = &payload[FIXED..];
    if data_length != data.len() || samples != data_length {
        return Err(format!(
            "field `data_length`: {data_length} (number_of_samples {samples}) but {} data bytes",
            data.len()
        ));
    }
    if data.is_empty() {
        return Err("field `data`: no samples".into());
    }
    if f64::from(angle_grad) >= GRADIANS_PER_TURN {
        return Err(format!("field `angle`: {angle_grad} grad is not below 400"));
    }
    if sample_period_ticks == 0 {
        return Err("field `sample_period`: 0".into());
    }
    Ok(DeviceData {
        gain_setting,
        angle_grad,
        transmit_duration_us,
        sample_period_ticks,
        transmit_frequency_khz,
        data,
    })
}

/// Builds a framed message (for tests of this reader and its users).
pub fn frame_message(id: u16, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(payload.len() + HEADER_BYTES + CHECKSUM_BYTES);
    out.extend_from_slice(b"BR");
    out.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    out.extend_from_slice(&id.to_le_bytes());
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(payload);
    let sum = out
        .iter()
        .fold(0u16, |acc, &b| acc.wrapping_add(u16::from(b)));
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// A `device_data` payload with the given angle, sample period and samples.
pub fn device_data_payload(angle_grad: u16, sample_period_ticks: u16, samples: &[u8]) -> Vec<u8> {
    let n = samples.len() as u16;
    let mut p = vec![1u8, 2];
    for v in [angle_grad, 5, sample_period_ticks, 750, n, n] {
        p.extend_from_slice(&v.to_le_bytes());
    }
    p.extend_from_slice(samples);
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checksum_of_a_real_message() {
        // From Sensor_Log_01__inside_base.bin: id 4, payload 02 43 03 01 01 00.
        let real = [
            0x42, 0x52, 6, 0, 4, 0, 2, 0, 0x02, 0x43, 3, 1, 1, 0, 0xea, 0,
        ];
        let framing = parse_messages(&real);
        assert_eq!(framing.messages.len(), 1);
        assert_eq!(framing.messages[0].id, 4);
        assert_eq!(framing.messages[0].payload, 8..14);
    }

    #[test]
    fn resyncs_after_noise_a_bad_checksum_and_reports_a_cut_tail() {
        let good = frame_message(DEVICE_DATA_ID, &device_data_payload(10, 444, &[1, 2, 3]));
        let mut bad = good.clone();
        bad[12] ^= 0x40;
        let mut stream = b"xxBRzz".to_vec();
        stream.extend_from_slice(&good);
        stream.extend_from_slice(&bad);
        stream.extend_from_slice(&good);
        stream.extend_from_slice(&good[..9]);
        let framing = parse_messages(&stream);
        assert_eq!(framing.messages.len(), 2);
        assert_eq!(framing.bad_checksums, 1);
        assert_eq!(framing.truncated_tail_bytes, 9);
        // 6 noise bytes plus the whole damaged message.
        assert_eq!(framing.skipped_bytes, 6 + good.len());
    }

    #[test]
    fn device_data_fields_and_bin_size() {
        let payload = device_data_payload(399, 444, &[7; 1200]);
        let d = decode_device_data(&payload).unwrap();
        assert_eq!((d.angle_grad, d.data.len()), (399, 1200));
        // The test payload's mode 1, gain 2, 5 us pulse at 750 kHz.
        assert_eq!(
            (
                d.gain_setting,
                d.transmit_duration_us,
                d.transmit_frequency_khz
            ),
            (2, 5, 750)
        );
        // 444 ticks: 0.5 * 1500 * 444 * 25e-9 = 8.325 mm, 9.99 m over 1200.
        assert!((d.bin_size_m() * 1200.0 - 9.99).abs() < 1e-9);
        assert!(decode_device_data(&device_data_payload(400, 444, &[1])).is_err());
        assert!(decode_device_data(&device_data_payload(0, 0, &[1])).is_err());
        assert!(decode_device_data(&payload[..20]).is_err());
    }
}
