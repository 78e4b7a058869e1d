//! Mutations of fuzz inputs: the damage real files suffer (cut off, bits
//! flipped, lines lost or doubled, numbers out of range) and some they
//! should not (byte-order marks, invalid UTF-8, NUL bytes).
//!
//! [`mutate_input`] picks one file of the input and applies one to four
//! mutations to it; every choice comes from the caller's seeded generator.

use super::Input;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Numbers that break parsers: zero, negative, huge, tiny, not finite,
/// past the integer types.
pub const NASTY_NUMBERS: [&str; 22] = [
    "0",
    "-0",
    "-1",
    "1",
    "1e308",
    "-1e308",
    "1e-320",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "1e20",
    "1e9",
    "-1e9",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "9223372036854775807",
    "-9223372036854775808",
    "1e",
    "0x10",
];

/// Applies one to four mutations to one file of `input`; `seeds` provide
/// material for splices.
pub fn mutate_input(input: &mut Input, seeds: &[Input], rng: &mut ChaCha8Rng) {
    if input.files.is_empty() {
        return;
    }
    let which = rng.random_range(0..input.files.len());
    let rounds = 1 + rng.random_range(0..4);
    for _ in 0..rounds {
        let donor = pick_donor(seeds, rng);
        mutate_bytes(&mut input.files[which].1, donor.as_deref(), rng);
    }
}

fn pick_donor(seeds: &[Input], rng: &mut ChaCha8Rng) -> Option<Vec<u8>> {
    let seed = seeds.get(rng.random_range(0..seeds.len().max(1)))?;
    let (_, bytes) = seed
        .files
        .get(rng.random_range(0..seed.files.len().max(1)))?;
    Some(bytes.clone())
}

/// One mutation of `bytes`; `donor` is another file to splice from.
pub fn mutate_bytes(bytes: &mut Vec<u8>, donor: Option<&[u8]>, rng: &mut ChaCha8Rng) {
    match rng.random_range(0..13) {
        0 => flip_bits(bytes, rng),
        1 => truncate(bytes, rng),
        2 => splice(bytes, donor, rng),
        3 | 4 => replace_number(bytes, rng),
        5 => duplicate_line(bytes, rng),
        6 => remove_line(bytes, rng),
        7 => overwrite_binary_value(bytes, rng),
        8 => insert_special(bytes, rng),
        9 => swap_lines(bytes, rng),
        10 => delete_range(bytes, rng),
        11 => cut_last_token(bytes),
        _ => set_random_bytes(bytes, rng),
    }
}

fn flip_bits(bytes: &mut [u8], rng: &mut ChaCha8Rng) {
    if bytes.is_empty() {
        return;
    }
    for _ in 0..rng.random_range(1..9) {
        let k = rng.random_range(0..bytes.len());
        bytes[k] ^= 1 << rng.random_range(0..8);
    }
}

fn set_random_bytes(bytes: &mut [u8], rng: &mut ChaCha8Rng) {
    if bytes.is_empty() {
        return;
    }
    for _ in 0..rng.random_range(1..5) {
        let k = rng.random_range(0..bytes.len());
        bytes[k] = rng.random();
    }
}

fn truncate(bytes: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    if !bytes.is_empty() {
        let at = rng.random_range(0..bytes.len());
        bytes.truncate(at);
    }
}

/// Removes the last byte or the last number: a file whose end was cut.
fn cut_last_token(bytes: &mut Vec<u8>) {
    while bytes.last().is_some_and(|b| b.is_ascii_whitespace()) {
        bytes.pop();
    }
    if bytes.len() > 1 {
        bytes.pop();
    }
}

fn delete_range(bytes: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    if bytes.is_empty() {
        return;
    }
    let start = rng.random_range(0..bytes.len());
    let len = rng.random_range(1..=(bytes.len() - start).min(64));
    bytes.drain(start..start + len);
}

/// Copies a piece of `donor` (or of `bytes` itself) over or into `bytes`.
fn splice(bytes: &mut Vec<u8>, donor: Option<&[u8]>, rng: &mut ChaCha8Rng) {
    let source = donor.map_or_else(|| bytes.clone(), <[u8]>::to_vec);
    if source.is_empty() {
        return;
    }
    let from = rng.random_range(0..source.len());
    let len = rng.random_range(1..=(source.len() - from).min(4096));
    let piece = &source[from..from + len];
    let at = rng.random_range(0..=bytes.len());
    if rng.random_bool(0.5) {
        bytes.splice(at..at, piece.iter().copied());
    } else {
        let end = (at + len).min(bytes.len());
        bytes.splice(at..end, piece.iter().copied());
    }
}

/// Byte ranges of the ASCII numbers in `bytes` (digits, signs, dots,
/// exponents), at most `limit` of them from a random start.
fn number_spans(bytes: &[u8], rng: &mut ChaCha8Rng, limit: usize) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    if bytes.is_empty() {
        return spans;
    }
    // Headers (counts, sizes, versions) sit at the start of a file and
    // steer everything after them: start there often, not only at a
    // uniformly random byte of a large file.
    let mut k = if rng.random_bool(0.3) {
        0
    } else {
        rng.random_range(0..bytes.len())
    };
    while k < bytes.len() && spans.len() < limit {
        if bytes[k].is_ascii_digit() {
            let mut start = k;
            while start > 0 && matches!(bytes[start - 1], b'0'..=b'9' | b'.' | b'-' | b'+') {
                start -= 1;
            }
            let mut end = k;
            while end < bytes.len()
                && matches!(bytes[end], b'0'..=b'9' | b'.' | b'-' | b'+' | b'e' | b'E')
            {
                end += 1;
            }
            spans.push((start, end));
            k = end;
        } else {
            k += 1;
        }
    }
    spans
}

fn replace_number(bytes: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    let spans = number_spans(bytes, rng, 32);
    if spans.is_empty() {
        overwrite_binary_value(bytes, rng);
        return;
    }
    let (start, end) = spans[rng.random_range(0..spans.len())];
    let replacement = if rng.random_bool(0.8) {
        NASTY_NUMBERS[rng.random_range(0..NASTY_NUMBERS.len())].to_string()
    } else {
        format!(
            "{}",
            rng.random::<f64>() * 10f64.powi(rng.random_range(-10..40))
        )
    };
    bytes.splice(start..end, replacement.bytes());
}

/// Line boundaries `(start, end_including_newline)`.
fn lines(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for (k, &b) in bytes.iter().enumerate() {
        if b == b'\n' {
            out.push((start, k + 1));
            start = k + 1;
        }
    }
    if start < bytes.len() {
        out.push((start, bytes.len()));
    }
    out
}

fn duplicate_line(bytes: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    let lines = lines(bytes);
    if lines.is_empty() {
        return;
    }
    let (start, end) = lines[rng.random_range(0..lines.len())];
    let line = bytes[start..end].to_vec();
    let (at, _) = lines[rng.random_range(0..lines.len())];
    bytes.splice(at..at, line);
}

fn remove_line(bytes: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    let lines = lines(bytes);
    if lines.is_empty() {
        return;
    }
    let (start, end) = lines[rng.random_range(0..lines.len())];
    bytes.drain(start..end);
}

fn swap_lines(bytes: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    let lines = lines(bytes);
    if lines.len() < 2 {
        return;
    }
    let k = rng.random_range(0..lines.len() - 1);
    let (a, b) = (lines[k], lines[k + 1]);
    let mut swapped = bytes[b.0..b.1].to_vec();
    if !swapped.ends_with(b"\n") {
        swapped.push(b'\n');
    }
    swapped.extend_from_slice(&bytes[a.0..a.1]);
    bytes.splice(a.0..b.1, swapped);
}

/// Overwrites 1, 2, 4 or 8 bytes with a boundary value of that width
/// (integers at their limits, floats NaN/∞/huge), little- or big-endian.
fn overwrite_binary_value(bytes: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    let value: Vec<u8> = match rng.random_range(0..10) {
        0 => vec![0xFF],
        1 => vec![0x00],
        2 => u16::MAX.to_le_bytes().to_vec(),
        3 => u32::MAX.to_le_bytes().to_vec(),
        4 => 0x8000_0000u32.to_le_bytes().to_vec(),
        5 => f64::NAN.to_le_bytes().to_vec(),
        6 => f64::INFINITY.to_le_bytes().to_vec(),
        7 => 1e308f64.to_le_bytes().to_vec(),
        8 => f32::NAN.to_le_bytes().to_vec(),
        _ => 3.0e38f32.to_le_bytes().to_vec(),
    };
    let value: Vec<u8> = if rng.random_bool(0.3) {
        value.into_iter().rev().collect()
    } else {
        value
    };
    if bytes.len() < value.len() {
        bytes.extend_from_slice(&value);
        return;
    }
    let at = rng.random_range(0..=bytes.len() - value.len());
    bytes[at..at + value.len()].copy_from_slice(&value);
}

/// Inserts a byte-order mark at the start, or invalid UTF-8, a NUL, a lone
/// CR, a tab or a very long run of digits somewhere.
fn insert_special(bytes: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    let at = rng.random_range(0..=bytes.len());
    let piece: Vec<u8> = match rng.random_range(0..7) {
        0 => {
            bytes.splice(0..0, [0xEF, 0xBB, 0xBF]);
            return;
        }
        1 => vec![0xFF],
        2 => vec![0xC3],
        3 => vec![0],
        4 => vec![b'\r'],
        5 => vec![b'\t'],
        _ => vec![b'9'; rng.random_range(1..400)],
    };
    bytes.splice(at..at, piece);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn mutations_are_deterministic_for_a_seed() {
        let base = b"EDGE_SE2 0 1 1.5 0 0 1 0 0 1 0 1\nVERTEX_SE2 0 0 0 0\n".to_vec();
        let run = |seed| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut input = Input::single("a.g2o", base.clone());
            for _ in 0..50 {
                mutate_input(&mut input, &[], &mut rng);
            }
            input
        };
        assert_eq!(run(3), run(3));
        assert_ne!(run(3), run(4));
    }

    #[test]
    fn number_replacement_replaces_a_whole_number() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut bytes = b"a 12.5e3 b".to_vec();
        replace_number(&mut bytes, &mut rng);
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.starts_with("a ") && text.ends_with(" b"), "{text}");
        assert!(!text.contains("12.5e3"), "{text}");
    }

    #[test]
    fn line_edits_keep_other_lines() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut bytes = b"one\ntwo\nthree\n".to_vec();
        remove_line(&mut bytes, &mut rng);
        assert_eq!(bytes.iter().filter(|&&b| b == b'\n').count(), 2);
        duplicate_line(&mut bytes, &mut rng);
        assert_eq!(bytes.iter().filter(|&&b| b == b'\n').count(), 3);
    }
}
