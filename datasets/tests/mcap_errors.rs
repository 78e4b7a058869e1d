//! Bad MCAP input: every failure is an error naming the file, the record and
//! the field, and nothing panics (truncations and random byte flips).

use echofield_datasets::DatasetError;
use echofield_datasets::mcap::fixture::random_mission;
use echofield_datasets::mcap::{json, read_mission, write_mission};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// `(topic, schema name, schema encoding, message encoding, log time, payload)`.
type RawMessage<'a> = (&'a str, &'a str, &'a str, &'a str, u64, Vec<u8>);

/// Writes an MCAP with the `mcap` crate directly.
fn write_raw(path: &Path, messages: &[RawMessage]) {
    let mut writer = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    let mut channels: BTreeMap<String, Arc<mcap::Channel>> = BTreeMap::new();
    for (topic, schema_name, schema_encoding, encoding, log_time, data) in messages {
        let next_id = channels.len() as u16 + 1;
        let channel = channels
            .entry(topic.to_string())
            .or_insert_with(|| {
                Arc::new(mcap::Channel {
                    id: next_id,
                    topic: topic.to_string(),
                    schema: Some(Arc::new(mcap::Schema {
                        id: next_id,
                        name: schema_name.to_string(),
                        encoding: schema_encoding.to_string(),
                        data: Cow::Owned(b"{}".to_vec()),
                    })),
                    message_encoding: encoding.to_string(),
                    metadata: BTreeMap::new(),
                })
            })
            .clone();
        writer
            .write(&mcap::Message {
                channel,
                sequence: 0,
                log_time: *log_time,
                publish_time: *log_time,
                data: Cow::Borrowed(data),
            })
            .unwrap();
    }
    writer.finish().unwrap();
}

fn json_msg<'a>(topic: &'a str, schema: &'a str, log_time: u64, text: &str) -> RawMessage<'a> {
    (
        topic,
        schema,
        "jsonschema",
        "json",
        log_time,
        text.as_bytes().to_vec(),
    )
}

const GOOD_BEAM: &str = r#"{"stamp_s":1.0,"angle_rad":0.0,"bin_size_m":0.1,"first_bin_range_m":0.0,"intensities":"AAE="}"#;

fn parse_error(err: DatasetError) -> (String, String, String) {
    match err {
        DatasetError::Parse {
            record,
            field,
            message,
            ..
        } => (record, field, message),
        other => panic!("expected a Parse error, got {other}"),
    }
}

#[test]
fn null_number_names_file_message_topic_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nan.mcap");
    // JSON has no NaN: serde_json and most writers turn it into null.
    write_raw(
        &path,
        &[
            json_msg("/sonar/beam", json::BEAM_SCHEMA_NAME, 1, GOOD_BEAM),
            json_msg(
                "/dvl/velocity",
                json::DVL_SCHEMA_NAME,
                2,
                r#"{"stamp_s":2.0,"velocity_mps":{"x":0.1,"y":null,"z":0},"valid":true}"#,
            ),
        ],
    );
    let err = read_mission(&path).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("nan.mcap"), "{text}");
    let (record, field, _) = parse_error(err);
    assert_eq!(record, "message 1 (topic `/dvl/velocity`)");
    assert_eq!(field, "velocity_mps.y");
}

#[test]
fn negative_stamp_and_bad_bin_size_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.mcap");
    let bad_bins = GOOD_BEAM.replace("\"bin_size_m\":0.1", "\"bin_size_m\":0");
    write_raw(
        &path,
        &[json_msg(
            "/sonar/beam",
            json::BEAM_SCHEMA_NAME,
            1,
            &bad_bins,
        )],
    );
    let (record, field, _) = parse_error(read_mission(&path).unwrap_err());
    assert_eq!(
        (record.as_str(), field.as_str()),
        ("message 0 (topic `/sonar/beam`)", "bin_size_m")
    );

    let negative = GOOD_BEAM.replace("\"stamp_s\":1.0", "\"stamp_s\":-5");
    write_raw(
        &path,
        &[json_msg(
            "/sonar/beam",
            json::BEAM_SCHEMA_NAME,
            1,
            &negative,
        )],
    );
    assert_eq!(parse_error(read_mission(&path).unwrap_err()).1, "stamp_s");

    let bad_base64 = GOOD_BEAM.replace("AAE=", "A*E=");
    write_raw(
        &path,
        &[json_msg(
            "/sonar/beam",
            json::BEAM_SCHEMA_NAME,
            1,
            &bad_base64,
        )],
    );
    assert_eq!(
        parse_error(read_mission(&path).unwrap_err()).1,
        "intensities"
    );

    write_raw(
        &path,
        &[json_msg(
            "/sonar/beam",
            json::BEAM_SCHEMA_NAME,
            1,
            "{\"stamp_s\":1.0",
        )],
    );
    let (record, _, message) = parse_error(read_mission(&path).unwrap_err());
    assert_eq!(record, "message 0 (topic `/sonar/beam`)");
    assert!(message.contains("EOF"), "{message}");
}

#[test]
fn unknown_schema_on_an_echofield_topic_is_an_error_and_other_topics_are_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("schemas.mcap");
    write_raw(
        &path,
        &[
            json_msg("/sonar/beam", json::BEAM_SCHEMA_NAME, 1, GOOD_BEAM),
            json_msg("/camera/info", "foo.CameraInfo", 2, "{}"),
        ],
    );
    let mission = read_mission(&path).unwrap();
    assert_eq!(mission.beams.len(), 1);
    assert_eq!(mission.name, "schemas", "no metadata: the file stem");
    assert_eq!(
        mission.mounting,
        echofield_frontend::sensors::SensorMounting::assumed_identity(),
        "no metadata: the identity mounting, marked as assumed"
    );

    write_raw(&path, &[json_msg("/dvl/velocity", "acme.Dvl", 1, "{}")]);
    let text = read_mission(&path).unwrap_err().to_string();
    assert!(
        text.contains("/dvl/velocity") && text.contains("acme.Dvl"),
        "{text}"
    );

    // A known schema in an encoding echofield does not decode.
    write_raw(
        &path,
        &[(
            "/sonar/beam",
            json::BEAM_SCHEMA_NAME,
            "protobuf",
            "protobuf",
            1,
            vec![1, 2],
        )],
    );
    let text = read_mission(&path).unwrap_err().to_string();
    assert!(text.contains("protobuf"), "{text}");
}

#[test]
fn two_channels_for_one_stream_are_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("twice.mcap");
    write_raw(
        &path,
        &[
            json_msg("/sonar/beam", json::BEAM_SCHEMA_NAME, 1, GOOD_BEAM),
            json_msg("/sonar2/beam", json::BEAM_SCHEMA_NAME, 2, GOOD_BEAM),
        ],
    );
    let text = read_mission(&path).unwrap_err().to_string();
    assert!(
        text.contains("/sonar/beam") && text.contains("/sonar2/beam"),
        "{text}"
    );
}

#[test]
fn files_that_are_not_missions() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.mcap");
    assert!(matches!(
        read_mission(&missing),
        Err(DatasetError::Io { .. })
    ));

    let empty = dir.path().join("empty.mcap");
    std::fs::write(&empty, b"").unwrap();
    let text = read_mission(&empty).unwrap_err().to_string();
    assert!(
        text.contains("empty.mcap") && text.contains("truncated"),
        "{text}"
    );

    let text_file = dir.path().join("notes.mcap");
    std::fs::write(&text_file, "% St Pere log\r\n1 2 3\r\n").unwrap();
    let text = read_mission(&text_file).unwrap_err().to_string();
    assert!(
        text.contains("notes.mcap") && text.contains("magic"),
        "{text}"
    );

    // A valid MCAP without any mission channel.
    let other = dir.path().join("camera.mcap");
    write_raw(
        &other,
        &[json_msg("/camera/info", "foo.CameraInfo", 2, "{}")],
    );
    let text = read_mission(&other).unwrap_err().to_string();
    assert!(text.contains("/camera/info"), "{text}");
}

#[test]
fn unsupported_format_version_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v2.mcap");
    let mut writer = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(&path).unwrap(),
    ))
    .unwrap();
    writer
        .write_metadata(&mcap::records::Metadata {
            name: "echofield.mission".into(),
            metadata: BTreeMap::from([
                ("format_version".into(), "2".into()),
                ("name".into(), "x".into()),
                ("mounting".into(), "{}".into()),
            ]),
        })
        .unwrap();
    writer.finish().unwrap();
    drop(writer);
    let (record, field, _) = parse_error(read_mission(&path).unwrap_err());
    assert_eq!(
        (record.as_str(), field.as_str()),
        ("metadata `echofield.mission`", "format_version")
    );
}

#[test]
fn every_truncation_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("full.mcap");
    write_mission(&path, &random_mission(120, 40, 5)).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.mcap");
    // Every length near both ends, and a stride through the middle.
    let lengths = (0..bytes.len().min(200))
        .chain((0..bytes.len()).step_by(97))
        .chain(bytes.len().saturating_sub(200)..bytes.len());
    for len in lengths {
        std::fs::write(&cut, &bytes[..len]).unwrap();
        match read_mission(&cut) {
            Ok(_) => panic!("a file cut to {len} of {} bytes was accepted", bytes.len()),
            Err(e) => assert!(e.to_string().contains("cut.mcap"), "{e}"),
        }
    }
}

/// Number of corrupted files per fuzz test; `ECHOFIELD_FUZZ_TRIALS=20000`
/// for a longer local run.
fn fuzz_trials() -> usize {
    std::env::var("ECHOFIELD_FUZZ_TRIALS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300)
}

#[test]
fn random_byte_flips_never_panic_nor_change_the_mission_silently() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("full.mcap");
    let mission = random_mission(120, 40, 9);
    write_mission(&path, &mission).unwrap();
    let original = read_mission(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let flipped = dir.path().join("flipped.mcap");
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let mut errors = 0;
    let trials = fuzz_trials();
    for _ in 0..trials {
        let mut corrupt = bytes.clone();
        for _ in 0..rng.random_range(1..=4) {
            // Half the flips hit the header/summary ends, where the
            // structure (lengths, offsets, opcodes) is dense.
            let at = if rng.random_bool(0.5) {
                rng.random_range(0..corrupt.len())
            } else {
                let k = rng.random_range(0..512.min(corrupt.len()));
                if rng.random_bool(0.5) {
                    k
                } else {
                    corrupt.len() - 1 - k
                }
            };
            corrupt[at] ^= rng.random_range(1..=255u8);
        }
        std::fs::write(&flipped, &corrupt).unwrap();
        match read_mission(&flipped) {
            // CRCs cover chunks, the data section and the summary, so a flip
            // can only be accepted if it left the content unchanged.
            Ok(read) => assert_eq!(read, original),
            Err(e) => {
                errors += 1;
                assert!(e.to_string().contains("flipped.mcap"), "{e}");
            }
        }
    }
    assert!(
        errors > trials * 9 / 10,
        "only {errors} of {trials} corruptions detected"
    );
}

/// Corrupt payloads inside a well-formed container (CRCs recomputed), so the
/// JSON and CDR decoders themselves see the damage.
#[test]
fn corrupt_payloads_with_valid_crcs_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let mission = random_mission(40, 16, 13);
    let json_path = dir.path().join("json.mcap");
    let ros2_path = dir.path().join("ros2.mcap");
    write_mission(&json_path, &mission).unwrap();
    echofield_datasets::mcap::write_mission_ros2(
        &ros2_path,
        &mission,
        echofield_datasets::mcap::Ros2GroundTruth::Odometry,
    )
    .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let out = dir.path().join("payloads.mcap");
    let trials = fuzz_trials() / 3;
    for source in [&json_path, &ros2_path] {
        let bytes = std::fs::read(source).unwrap();
        let messages: Vec<mcap::Message> = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .collect();
        for _ in 0..trials {
            let victim = rng.random_range(0..messages.len());
            let mut writer = mcap::Writer::new(std::io::BufWriter::new(
                std::fs::File::create(&out).unwrap(),
            ))
            .unwrap();
            for (k, m) in messages.iter().enumerate() {
                let mut m = m.clone();
                if k == victim {
                    let mut data = m.data.into_owned();
                    if rng.random_bool(0.3) {
                        data.truncate(rng.random_range(0..=data.len()));
                    } else {
                        for _ in 0..rng.random_range(1..=3) {
                            let at = rng.random_range(0..data.len());
                            data[at] ^= rng.random_range(1..=255u8);
                        }
                    }
                    m.data = Cow::Owned(data);
                }
                writer.write(&m).unwrap();
            }
            writer.finish().unwrap();
            drop(writer);
            // Either a value the checks accept, or an error naming the message.
            if let Err(e) = read_mission(&out) {
                let text = e.to_string();
                assert!(text.contains(&format!("message {victim} ")), "{text}");
            }
        }
    }
}

/// Regression: `mcap` 0.24's streaming chunk decompression spins forever on
/// some corrupt zstd frames (no progress check in its `decompress_inner`);
/// the byte-flip test above hit it (seed 2024, trial 174). The file is the
/// smallest case found: a 3-beam mission with one bit flipped in the
/// compressed chunk (byte 324, xor 0x10).
#[test]
fn corrupt_zstd_frame_that_stalled_the_mcap_crate_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zstd_no_progress.mcap");
    std::fs::write(&path, include_bytes!("mcap_data/zstd_no_progress.mcap")).unwrap();
    let text = read_mission(&path).unwrap_err().to_string();
    assert!(
        text.contains("zstd_no_progress.mcap") && text.contains("chunk"),
        "{text}"
    );
}

/// A zstd frame cut short inside a chunk record whose own size fields stay
/// consistent.
#[test]
fn zstd_frame_cut_inside_a_consistent_chunk_record_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("full.mcap");
    write_mission(&path, &random_mission(60, 40, 3)).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    // Walk the records after the 8-byte magic to the first Chunk (opcode 6).
    let mut at = 8;
    while bytes[at] != 0x06 {
        at += 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    }
    let record_len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    let body = at + 9;
    // Chunk body: start, end, uncompressed size (u64 each), crc (u32),
    // compression (u32 length + text), compressed size (u64), data.
    let compression_len = u32::from_le_bytes(bytes[body + 28..body + 32].try_into().unwrap());
    let size_at = body + 32 + compression_len as usize;
    let compressed = u64::from_le_bytes(bytes[size_at..size_at + 8].try_into().unwrap()) as usize;
    let data_at = size_at + 8;
    let cut_path = dir.path().join("cut_frame.mcap");
    for cut in [1, 3, 8, 64, compressed / 2] {
        let mut out = bytes[..at + 1].to_vec();
        out.extend_from_slice(&((record_len - cut) as u64).to_le_bytes());
        out.extend_from_slice(&bytes[body..size_at]);
        out.extend_from_slice(&((compressed - cut) as u64).to_le_bytes());
        out.extend_from_slice(&bytes[data_at..data_at + compressed - cut]);
        out.extend_from_slice(&bytes[data_at + compressed..]);
        std::fs::write(&cut_path, &out).unwrap();
        let text = read_mission(&cut_path).unwrap_err().to_string();
        assert!(
            text.contains("cut_frame.mcap") && text.contains("chunk"),
            "{text}"
        );
    }
}

/// `/position/fix`: a bad value is an error naming the file, the message
/// and the field; fixes out of time order are re-sorted with a warning
/// that names the stream and the first of them.
#[test]
fn bad_position_fixes_are_named_and_late_ones_resorted() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fixes.mcap");
    let fix = |stamp: f64, extra: &str| {
        format!(r#"{{"stamp_s":{stamp},"x_m":10.0,"y_m":-4.0,"std_m":2.0{extra}}}"#)
    };
    let schema = json::POSITION_FIX_SCHEMA_NAME;
    for (text, field) in [
        (
            fix(2.0, "").replace("\"std_m\":2.0", "\"std_m\":null"),
            "std_m",
        ),
        (
            fix(2.0, "").replace("\"std_m\":2.0", "\"std_m\":-1"),
            "std_m",
        ),
        (fix(2.0, "").replace("\"x_m\":10.0", "\"x_m\":5e7"), "x_m"),
        (fix(2.0, ",\"z_m\":1"), "z_m"),
    ] {
        write_raw(
            &path,
            &[
                json_msg("/sonar/beam", json::BEAM_SCHEMA_NAME, 1, GOOD_BEAM),
                json_msg("/position/fix", schema, 2, &text),
            ],
        );
        let err = read_mission(&path).unwrap_err();
        assert!(err.to_string().contains("fixes.mcap"), "{err}");
        let (record, f, message) = parse_error(err);
        assert_eq!(record, "message 1 (topic `/position/fix`)", "{text}");
        assert_eq!(f, field, "{text}: {message}");
    }

    write_raw(
        &path,
        &[
            json_msg("/sonar/beam", json::BEAM_SCHEMA_NAME, 1, GOOD_BEAM),
            json_msg("/position/fix", schema, 2, &fix(5.0, "")),
            json_msg("/position/fix", schema, 3, &fix(7.0, "")),
            json_msg("/position/fix", schema, 4, &fix(6.0, "")),
        ],
    );
    let mission = read_mission(&path).unwrap();
    let stamps: Vec<f64> = mission.position_fixes.iter().map(|f| f.stamp_s).collect();
    assert_eq!(stamps, [5.0, 6.0, 7.0]);
    let warning = mission
        .warnings
        .of(echofield_frontend::warnings::WarningKind::StampsResorted)
        .unwrap();
    assert_eq!(warning.count, 1);
    assert!(warning.message.contains("position fixes"), "{warning:?}");
    assert_eq!(
        warning.first_record.as_deref(),
        Some("position fixes record 2")
    );
}
