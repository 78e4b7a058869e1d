//! Structured random inputs: files that follow a format's grammar (right
//! tags, right column counts, framed binary records) with values drawn
//! from plausible ranges and, now and then, from [`NASTY_NUMBERS`].

use super::mutate::NASTY_NUMBERS;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::fmt::Write as _;

/// A number as text: usually `around ± spread`, sometimes a nasty value.
pub fn number(rng: &mut ChaCha8Rng, around: f64, spread: f64, nasty: f64) -> String {
    if rng.random_bool(nasty) {
        return NASTY_NUMBERS[rng.random_range(0..NASTY_NUMBERS.len())].to_string();
    }
    let value = around + spread * (2.0 * rng.random::<f64>() - 1.0);
    if rng.random_bool(0.2) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

/// An integer id in `0..n`, sometimes out of range or not an id.
pub fn id(rng: &mut ChaCha8Rng, n: u64, nasty: f64) -> String {
    if rng.random_bool(nasty) {
        return NASTY_NUMBERS[rng.random_range(0..NASTY_NUMBERS.len())].to_string();
    }
    rng.random_range(0..n.max(1)).to_string()
}

/// The same text with every numeric token of every data line replaced by a
/// random value of similar size (lines starting with `%`, `#` or a word
/// are kept as they are), and some lines dropped or repeated: a file of
/// the same layout with other values.
pub fn regenerate_numbers(text: &[u8], rng: &mut ChaCha8Rng, nasty: f64) -> Vec<u8> {
    let mut out = Vec::with_capacity(text.len());
    for line in text.split_inclusive(|&b| b == b'\n') {
        let repeats = match rng.random_range(0..40) {
            0 => 0,
            1 => 2,
            _ => 1,
        };
        for _ in 0..repeats {
            out.extend(regenerate_line(line, rng, nasty));
        }
    }
    out
}

fn regenerate_line(line: &[u8], rng: &mut ChaCha8Rng, nasty: f64) -> Vec<u8> {
    let Ok(text) = std::str::from_utf8(line) else {
        return line.to_vec();
    };
    if text.trim_start().starts_with(['%', '#']) {
        return line.to_vec();
    }
    let mut out = String::with_capacity(text.len());
    let mut token = String::new();
    let flush = |token: &mut String, out: &mut String, rng: &mut ChaCha8Rng| {
        if token.is_empty() {
            return;
        }
        match token.parse::<f64>() {
            Ok(v) if v.is_finite() => {
                let is_integer = !token.contains(['.', 'e', 'E']);
                if is_integer && !rng.random_bool(nasty) {
                    let spread = (v.abs() * 0.1).max(3.0) as i64;
                    let shifted = (v as i64).saturating_add(rng.random_range(-spread..=spread));
                    out.push_str(&shifted.max(0).to_string());
                } else {
                    out.push_str(&number(rng, v, v.abs() * 0.1 + 1.0, nasty));
                }
            }
            _ => out.push_str(token),
        }
        token.clear();
    };
    for c in text.chars() {
        if c.is_whitespace() || c == ',' {
            flush(&mut token, &mut out, rng);
            out.push(c);
        } else {
            token.push(c);
        }
    }
    flush(&mut token, &mut out, rng);
    out.into_bytes()
}

/// A random 2D pose graph as g2o (`toro = false`) or TORO text: a chain of
/// odometry edges, a few loops, optional vertices, priors and FIX lines.
pub fn pose_graph_text(rng: &mut ChaCha8Rng, toro: bool) -> Vec<u8> {
    let n: u64 = rng.random_range(1..60);
    let nasty = if rng.random_bool(0.5) { 0.0 } else { 0.02 };
    let mut text = String::new();
    let with_vertices = rng.random_bool(0.7);
    let (vertex, edge) = if toro {
        ("VERTEX2", "EDGE2")
    } else {
        ("VERTEX_SE2", "EDGE_SE2")
    };
    if with_vertices {
        for k in 0..n {
            let _ = writeln!(
                text,
                "{vertex} {} {} {} {}",
                if rng.random_bool(nasty) {
                    id(rng, n, 1.0)
                } else {
                    k.to_string()
                },
                number(rng, k as f64, 1.0, nasty),
                number(rng, 0.0, 1.0, nasty),
                number(rng, 0.0, 3.2, nasty)
            );
        }
    }
    let edges = n.saturating_sub(1) + rng.random_range(0..n);
    for k in 0..edges {
        let (from, to) = if k + 1 < n {
            (k.to_string(), (k + 1).to_string())
        } else {
            (id(rng, n, nasty), id(rng, n, nasty))
        };
        let _ = write!(text, "{edge} {from} {to}");
        edge_values(rng, &mut text, toro, nasty);
        text.push('\n');
    }
    if !toro && rng.random_bool(0.3) {
        let _ = writeln!(text, "FIX {}", id(rng, n + 2, nasty));
    }
    if !toro && rng.random_bool(0.2) {
        let _ = writeln!(
            text,
            "EDGE_PRIOR_SE2 {} 0 0 0 1 0 0 1 0 1",
            id(rng, n + 2, nasty)
        );
    }
    if rng.random_bool(0.1) {
        // A file cut in its last number.
        while text.ends_with(['\n', ' ']) {
            text.pop();
        }
        text.pop();
    }
    text.into_bytes()
}

/// Appends the measurement `x y θ` and the six information values of an
/// edge line (g2o: I11 I12 I13 I22 I23 I33; TORO: xx xy yy tt xt yt), each
/// spoilt with probability `nasty`.
fn edge_values(rng: &mut ChaCha8Rng, text: &mut String, toro: bool, nasty: f64) {
    let _ = write!(
        text,
        " {} {} {}",
        number(rng, 1.0, 1.0, nasty),
        number(rng, 0.0, 1.0, nasty),
        number(rng, 0.0, 3.2, nasty)
    );
    let diagonal_slots: [bool; 6] = if toro {
        [true, false, true, true, false, false]
    } else {
        [true, false, false, true, false, true]
    };
    for diagonal in diagonal_slots {
        let value = if diagonal {
            number(rng, 100.0, 99.0, nasty)
        } else {
            number(rng, 0.0, 1.0, nasty)
        };
        let _ = write!(text, " {value}");
    }
}

/// A random TUM trajectory: increasing stamps, unit quaternions about z.
pub fn tum_text(rng: &mut ChaCha8Rng) -> Vec<u8> {
    let n = rng.random_range(1..80);
    let nasty = if rng.random_bool(0.5) { 0.0 } else { 0.02 };
    let mut text = String::new();
    if rng.random_bool(0.3) {
        text.push_str("# timestamp tx ty tz qx qy qz qw\n");
    }
    let mut stamp = rng.random_range(0.0..2e9);
    for _ in 0..n {
        stamp += rng.random_range(0.0..2.0);
        let half: f64 = rng.random_range(-1.6..1.6);
        let _ = writeln!(
            text,
            "{} {} {} {} 0 0 {} {}",
            number(rng, stamp, 0.0, nasty),
            number(rng, 0.0, 100.0, nasty),
            number(rng, 0.0, 100.0, nasty),
            number(rng, 0.0, 1.0, nasty),
            number(rng, half.sin(), 0.0, nasty),
            number(rng, half.cos(), 0.0, nasty)
        );
    }
    text.into_bytes()
}

/// A Qt data stream string: u32 big-endian byte length, UTF-16BE text.
pub fn qstring(text: &str) -> Vec<u8> {
    let units: Vec<u8> = text.encode_utf16().flat_map(u16::to_be_bytes).collect();
    let mut out = (units.len() as u32).to_be_bytes().to_vec();
    out.extend(units);
    out
}

/// A Ping Viewer log: the header `header` (taken from a real log) and
/// random records of framed Ping360 messages, mostly `device_data`.
pub fn ping360_log(rng: &mut ChaCha8Rng, header: &[u8]) -> Vec<u8> {
    use echofield_datasets::ping360::protocol::{
        DEVICE_DATA_ID, device_data_payload, frame_message,
    };
    let mut out = header.to_vec();
    let mut elapsed_ms: u64 = rng.random_range(0..10_000);
    let period: u16 = if rng.random_bool(0.1) {
        rng.random()
    } else {
        rng.random_range(80..900)
    };
    let samples = if rng.random_bool(0.1) {
        rng.random_range(0..3000)
    } else {
        rng.random_range(1..300)
    };
    let mut angle: u16 = rng.random_range(0..400);
    for _ in 0..rng.random_range(1..60) {
        elapsed_ms += rng.random_range(0..200);
        let stamp = if rng.random_bool(0.05) {
            ["", "1:2:3", "99:99:99.999", "00:00:00.", "۰۰:۰۰:۰۲.۵۷۱"][rng.random_range(0..5)]
                .to_string()
        } else {
            format!(
                "{:02}:{:02}:{:02}.{:03}",
                elapsed_ms / 3_600_000,
                elapsed_ms / 60_000 % 60,
                elapsed_ms / 1000 % 60,
                elapsed_ms % 1000
            )
        };
        out.extend(qstring(&stamp));
        let mut chunk = Vec::new();
        for _ in 0..rng.random_range(0..4) {
            angle = if rng.random_bool(0.05) {
                rng.random()
            } else {
                (angle + 1) % 400
            };
            let data: Vec<u8> = (0..samples).map(|_| rng.random()).collect();
            let id = if rng.random_bool(0.9) {
                DEVICE_DATA_ID
            } else {
                rng.random_range(0..3000)
            };
            chunk.extend(frame_message(
                id,
                &device_data_payload(angle, period, &data),
            ));
        }
        // Split the serial stream at an arbitrary point, as a serial port does.
        out.extend((chunk.len() as u32).to_be_bytes());
        out.extend(chunk);
    }
    out
}

/// One ROS 1 bag record: header fields, then data.
fn bag_record(fields: &[(&str, Vec<u8>)], data: &[u8]) -> Vec<u8> {
    let mut header = Vec::new();
    for (name, value) in fields {
        let field_len = (name.len() + 1 + value.len()) as u32;
        header.extend(field_len.to_le_bytes());
        header.extend(name.as_bytes());
        header.push(b'=');
        header.extend(value);
    }
    let mut out = (header.len() as u32).to_le_bytes().to_vec();
    out.extend(header);
    out.extend((data.len() as u32).to_le_bytes());
    out.extend(data);
    out
}

/// A ROS 1 bag (format 2.0) with one AcousticBeam connection and random
/// beams, in one uncompressed chunk or as top-level records.
pub fn miniking_bag(rng: &mut ChaCha8Rng) -> Vec<u8> {
    let conn: u32 = if rng.random_bool(0.95) {
        0
    } else {
        rng.random()
    };
    let mut records = miniking_connection_record();
    let mut stamp_s: f64 = rng.random_range(0.0..2e9);
    for _ in 0..rng.random_range(0..40) {
        stamp_s += rng.random_range(0.0..0.2);
        let beam = random_acoustic_beam(rng, stamp_s);
        let secs = stamp_s as u32;
        let nsecs = ((stamp_s - f64::from(secs)) * 1e9) as u32;
        let mut time = secs.to_le_bytes().to_vec();
        time.extend(nsecs.to_le_bytes());
        records.extend(bag_record(
            &[
                ("op", vec![0x02]),
                ("conn", conn.to_le_bytes().to_vec()),
                ("time", time),
            ],
            &echofield_datasets::miniking::acoustic_beam::encode_acoustic_beam(&beam),
        ));
    }
    let mut out = b"#ROSBAG V2.0\n".to_vec();
    out.extend(bag_record(
        &[
            ("op", vec![0x03]),
            ("index_pos", 0u64.to_le_bytes().to_vec()),
            ("conn_count", 1u32.to_le_bytes().to_vec()),
            ("chunk_count", 1u32.to_le_bytes().to_vec()),
        ],
        &[],
    ));
    if rng.random_bool(0.7) {
        out.extend(bag_record(
            &[
                ("op", vec![0x05]),
                ("compression", b"none".to_vec()),
                ("size", (records.len() as u32).to_le_bytes().to_vec()),
            ],
            &records,
        ));
    } else {
        out.extend(records);
    }
    out
}

/// The connection record (op 0x07, connection 0) of the MiniKing sonar
/// topic with its AcousticBeam type.
fn miniking_connection_record() -> Vec<u8> {
    use echofield_datasets::miniking::acoustic_beam::{ACOUSTIC_BEAM_MD5, ACOUSTIC_BEAM_TYPE};
    let topic = "/miniking_node/sonar";
    let mut connection_header = Vec::new();
    for (name, value) in [
        ("topic", topic),
        ("type", ACOUSTIC_BEAM_TYPE),
        ("md5sum", ACOUSTIC_BEAM_MD5),
        ("message_definition", "# fuzz"),
    ] {
        let field = format!("{name}={value}");
        connection_header.extend((field.len() as u32).to_le_bytes());
        connection_header.extend(field.as_bytes());
    }
    bag_record(
        &[
            ("op", vec![0x07]),
            ("conn", 0u32.to_le_bytes().to_vec()),
            ("topic", topic.as_bytes().to_vec()),
        ],
        &connection_header,
    )
}

/// A random beam at `stamp_s`; with probability 0.05 each, a zero stamp, a
/// random-bits angle or range and a bin count that disagrees with the
/// intensities.
fn random_acoustic_beam(
    rng: &mut ChaCha8Rng,
    stamp_s: f64,
) -> echofield_datasets::miniking::acoustic_beam::AcousticBeam {
    let bins: usize = rng.random_range(0..300);
    echofield_datasets::miniking::acoustic_beam::AcousticBeam {
        seq: rng.random(),
        stamp_s: if rng.random_bool(0.05) { 0.0 } else { stamp_s },
        frame_id: "sonar".into(),
        angle_deg: if rng.random_bool(0.05) {
            f32::from_bits(rng.random())
        } else {
            rng.random_range(0.0..360.0)
        },
        range_max_m: if rng.random_bool(0.05) {
            f32::from_bits(rng.random())
        } else {
            rng.random_range(0.1..100.0)
        },
        bins: if rng.random_bool(0.05) {
            rng.random()
        } else {
            bins as i32
        },
        intensities: (0..bins).map(|_| rng.random()).collect(),
    }
}
