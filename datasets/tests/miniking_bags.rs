//! The real MiniKing bags committed under `datasets/msis-real/miniking/`, and
//! damaged copies. Expected values come from the README of the bags and an
//! independent scan, not from this reader. Print the measured facts with
//! `cargo test -p echofield-datasets --test miniking_bags -- --nocapture`.

use echofield_datasets::DatasetError;
use echofield_datasets::miniking::acoustic_beam::{AcousticBeam, encode_acoustic_beam};
use echofield_datasets::miniking::read_miniking_bag;
use std::f64::consts::TAU;
use std::path::PathBuf;

fn bag(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("msis-real/miniking")
        .join(name)
}

const FULL: &str = "full_sonar_scan_2015-05-26-11-38-04.bag";
const NARROW: &str = "narrow_sonar_scan_2015-05-26-11-41-49.bag";

#[test]
fn full_scan_has_875_beams_of_30_m_over_200_bins() {
    let rec = read_miniking_bag(&bag(FULL)).unwrap();
    assert_eq!(rec.beams.len(), 875);
    assert!(rec.stats.stopped_early.is_none());
    let segs = rec.range_segments();
    assert_eq!(segs.len(), 1);
    assert_eq!(segs[0].bins, 200);
    assert!((segs[0].bin_size_m - 0.15).abs() < 1e-6);
    // First beam at 126.9 deg; 0.9 deg steps; ~2.2 rotations in 41.6 s.
    assert!((rec.beams[0].angle_rad.to_degrees() - 126.9).abs() < 1e-4);
    let step = echofield_graph::wrap_angle(rec.beams[1].angle_rad - rec.beams[0].angle_rad);
    assert!((step.to_degrees() - 0.9).abs() < 1e-4);
    let turns = segs[0].swept_rad / TAU;
    assert!((turns - 2.18).abs() < 0.05, "{turns}");
    let span_s = rec.beams.last().unwrap().stamp_s - rec.beams[0].stamp_s;
    assert!((span_s - 41.6).abs() < 0.2, "{span_s}");
    // header.stamp of the first message (2015-05-26 09:38:05 UTC).
    assert!((rec.beams[0].stamp_s - 1432633085.1703).abs() < 1e-3);
    assert_eq!(
        rec.info[0].1,
        "/miniking_node/sonar [miniking_ros/AcousticBeam]"
    );
}

#[test]
fn narrow_scan_sweeps_a_sector_around_180_deg() {
    let rec = read_miniking_bag(&bag(NARROW)).unwrap();
    assert_eq!(rec.beams.len(), 566);
    let degrees: Vec<f64> = rec
        .beams
        .iter()
        .map(|b| b.angle_rad.to_degrees().rem_euclid(360.0))
        .collect();
    let (lo, hi) = degrees
        .iter()
        .fold((360.0f64, 0.0f64), |(l, h), &d| (l.min(d), h.max(d)));
    assert!(
        (lo - 178.2).abs() < 0.01 && (hi - 180.9).abs() < 0.01,
        "{lo} {hi}"
    );
    // Sweeps back and forth in 0.45 deg steps.
    let steps: Vec<f64> = rec
        .beams
        .windows(2)
        .map(|w| echofield_graph::wrap_angle(w[1].angle_rad - w[0].angle_rad).to_degrees())
        .collect();
    assert!(
        steps
            .iter()
            .all(|s| (s.abs() - 0.45).abs() < 1e-3 || s.abs() < 1e-3)
    );
    assert!(steps.iter().any(|&s| s > 0.0) && steps.iter().any(|&s| s < 0.0));
}

fn edited(name: &str, edit: impl FnOnce(&mut Vec<u8>)) -> (tempfile::TempDir, PathBuf) {
    let mut bytes = std::fs::read(bag(name)).unwrap();
    edit(&mut bytes);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    (dir, path)
}

fn find(bytes: &[u8], needle: &[u8], from: usize) -> usize {
    from + bytes[from..]
        .windows(needle.len())
        .position(|w| w == needle)
        .unwrap()
}

#[test]
fn a_bag_cut_in_its_chunk_keeps_the_whole_messages_before_the_cut() {
    // The single chunk spans most of the file; its data starts at byte 4166
    // with a 1140-byte connection record, then 283-byte message records, so
    // the first 100 000 bytes hold 334 whole messages (counted with a
    // separate script).
    let (_dir, path) = edited(FULL, |b| b.truncate(100_000));
    let rec = read_miniking_bag(&path).unwrap();
    assert_eq!(rec.beams.len(), 334);
    let stop = rec.stats.stopped_early.as_ref().unwrap();
    assert!(
        stop.starts_with("record 1 at byte") && stop.contains("truncated"),
        "{stop}"
    );
    // Each kept beam is whole.
    assert!(rec.beams.iter().all(|b| b.intensities.len() == 200));
}

#[test]
fn a_bag_cut_in_its_index_keeps_every_beam() {
    // The index section after the chunk is not needed.
    let len = std::fs::metadata(bag(FULL)).unwrap().len() as usize;
    let (_dir, path) = edited(FULL, |b| b.truncate(len - 100));
    let rec = read_miniking_bag(&path).unwrap();
    assert_eq!(rec.beams.len(), 875);
    assert!(
        rec.stats
            .stopped_early
            .as_ref()
            .unwrap()
            .contains("truncated")
    );
}

#[test]
fn compressed_chunks_are_a_clear_error() {
    let (_dir, path) = edited(FULL, |b| {
        let at = find(b, b"compression=none", 0);
        b[at + 12..at + 16].copy_from_slice(b"bz2\0");
    });
    let err = read_miniking_bag(&path).unwrap_err();
    assert!(matches!(err, DatasetError::Format { .. }), "{err}");
    assert!(err.to_string().contains("bz2"), "{err}");
}

#[test]
fn a_beam_with_wrong_bin_count_names_message_and_field() {
    let (_dir, path) = edited(FULL, |b| {
        // The bins field (int32 200) of the 11th message: after frame_id
        // "sonar" and range_max 30.0 (0x41f00000).
        let mut at = 0;
        for _ in 0..11 {
            at = find(
                b,
                &[5, 0, 0, 0, b's', b'o', b'n', b'a', b'r', 0, 0, 0xf0, 0x41],
                at + 1,
            );
        }
        b[at + 13] = 199;
    });
    let err = read_miniking_bag(&path).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, DatasetError::Parse { .. }), "{text}");
    assert!(
        text.contains("message 10 (byte") && text.contains("field `bins`: 199 but 200"),
        "{text}"
    );
}

#[test]
fn a_stamp_going_back_names_the_message() {
    let (_dir, path) = edited(FULL, |b| {
        // header.stamp.sec of the 6th message (bytes 4-7 of its data); the
        // data starts after seq. Set it one day back.
        let mut at = 0;
        for _ in 0..6 {
            at = find(b, &[5, 0, 0, 0, b's', b'o', b'n', b'a', b'r'], at + 1);
        }
        let sec_at = at - 8;
        let sec = u32::from_le_bytes(b[sec_at..sec_at + 4].try_into().unwrap()) - 86_400;
        b[sec_at..sec_at + 4].copy_from_slice(&sec.to_le_bytes());
    });
    let err = read_miniking_bag(&path).unwrap_err().to_string();
    assert!(
        err.contains("message 5") && err.contains("field `header.stamp`"),
        "{err}"
    );
}

#[test]
fn not_a_bag_is_a_format_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.bag");
    std::fs::write(&path, b"#ROSBAG V1.2\n").unwrap();
    let err = read_miniking_bag(&path).unwrap_err();
    assert!(matches!(err, DatasetError::Format { .. }), "{err}");
}

#[test]
fn a_synthetic_bag_round_trips() {
    let beams: Vec<AcousticBeam> = (0..3)
        .map(|i| AcousticBeam {
            seq: i,
            stamp_s: 100.0 + f64::from(i) * 0.05,
            frame_id: "sonar".into(),
            range_max_m: 10.0,
            bins: 4,
            angle_deg: 350.0 + 5.0 * i as f32,
            intensities: vec![i as u8; 4],
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.bag");
    std::fs::write(&path, synthetic_bag(&beams)).unwrap();
    let rec = read_miniking_bag(&path).unwrap();
    assert_eq!(rec.beams.len(), 3);
    assert!((rec.beams[2].stamp_s - 100.1).abs() < 1e-6);
    assert!((rec.beams[0].bin_size_m - 2.5).abs() < 1e-12);
    // 350 deg = -10 deg; 360 deg = 0.
    assert!((rec.beams[0].angle_rad.to_degrees() + 10.0).abs() < 1e-4);
    assert!(rec.beams[2].angle_rad.abs() < 1e-6);
    assert_eq!(rec.beams[1].intensities, vec![1; 4]);
}

#[test]
fn measured_facts() {
    for name in [FULL, NARROW] {
        let rec = read_miniking_bag(&bag(name)).unwrap();
        let span = rec.beams.last().unwrap().stamp_s - rec.beams[0].stamp_s;
        println!(
            "{name}: {} beams in {span:.1} s ({:.1} ms/beam), {} records, {} messages",
            rec.beams.len(),
            1e3 * span / (rec.beams.len() - 1) as f64,
            rec.stats.records,
            rec.stats.messages
        );
        for seg in rec.range_segments() {
            println!(
                "  {:.1} m ({} bins of {:.3} m): {} beams, {:.2} turns swept",
                seg.range_m(),
                seg.bins,
                seg.bin_size_m,
                seg.beam_count,
                seg.swept_rad / TAU
            );
        }
    }
}

/// A bag 2.0 with one connection and one uncompressed chunk (no index).
fn synthetic_bag(beams: &[AcousticBeam]) -> Vec<u8> {
    fn field(out: &mut Vec<u8>, name: &str, value: &[u8]) {
        out.extend_from_slice(&((name.len() + 1 + value.len()) as u32).to_le_bytes());
        out.extend_from_slice(name.as_bytes());
        out.push(b'=');
        out.extend_from_slice(value);
    }
    fn record(out: &mut Vec<u8>, header: &[u8], data: &[u8]) {
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        out.extend_from_slice(header);
        out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        out.extend_from_slice(data);
    }
    let mut chunk = Vec::new();
    let mut h = Vec::new();
    field(&mut h, "op", &[7]);
    field(&mut h, "conn", &0u32.to_le_bytes());
    field(&mut h, "topic", b"/miniking_node/sonar");
    let mut d = Vec::new();
    field(&mut d, "topic", b"/miniking_node/sonar");
    field(&mut d, "type", b"miniking_ros/AcousticBeam");
    field(&mut d, "md5sum", b"8500cd97501a86f9b35f0c89c7f66259");
    record(&mut chunk, &h, &d);
    for beam in beams {
        let mut h = Vec::new();
        field(&mut h, "op", &[2]);
        field(&mut h, "conn", &0u32.to_le_bytes());
        let mut time = (beam.stamp_s as u32).to_le_bytes().to_vec();
        time.extend_from_slice(&0u32.to_le_bytes());
        field(&mut h, "time", &time);
        record(&mut chunk, &h, &encode_acoustic_beam(beam));
    }
    let mut out = b"#ROSBAG V2.0\n".to_vec();
    let mut h = Vec::new();
    field(&mut h, "op", &[5]);
    field(&mut h, "compression", b"none");
    field(&mut h, "size", &(chunk.len() as u32).to_le_bytes());
    record(&mut out, &h, &chunk);
    out
}

#[test]
fn random_damage_never_panics() {
    use rand::{Rng, SeedableRng};
    let original = std::fs::read(bag(NARROW)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("damaged.bag");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    for _ in 0..60 {
        let mut bytes = original.clone();
        for _ in 0..rng.random_range(1..10) {
            let at = rng.random_range(0..bytes.len());
            bytes[at] = rng.random();
        }
        let cut = rng.random_range(0..=bytes.len());
        bytes.truncate(cut);
        std::fs::write(&path, &bytes).unwrap();
        // Either result is fine; a panic fails the test.
        if let Ok(rec) = read_miniking_bag(&path) {
            assert!(
                rec.beams
                    .iter()
                    .all(|b| b.bin_size_m > 0.0 && b.intensities.len() == 200)
            );
        }
    }
}
