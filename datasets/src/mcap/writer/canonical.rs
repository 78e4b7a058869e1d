//! Deterministic summary section.
//!
//! The `mcap` crate (0.24) writes the Schema and Channel records of the
//! summary section in `HashMap` order, which changes from run to run, so two
//! writes of the same mission would differ. This pass sorts each run of
//! Schema and of Channel records in the finished file by id. The records keep
//! their sizes, so every offset in the summary stays valid; only the summary
//! CRC in the footer is recomputed.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};

const OP_FOOTER: u8 = 0x02;
const OP_SCHEMA: u8 = 0x03;
const OP_CHANNEL: u8 = 0x04;
const MAGIC_LEN: u64 = 8;
/// opcode (1) + length (8) + summary_start, summary_offset_start (8 + 8) + crc (4).
const FOOTER_RECORD_LEN: u64 = 1 + 8 + 20;

fn invalid(message: &str) -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::InvalidData, message.to_string())
}

/// Splits a run of records into `(opcode, bytes of the whole record)`.
fn split_records(mut bytes: &[u8]) -> std::io::Result<Vec<(u8, &[u8])>> {
    let mut records = Vec::new();
    while !bytes.is_empty() {
        if bytes.len() < 9 {
            return Err(invalid("summary record header cut short"));
        }
        let len = u64::from_le_bytes(bytes[1..9].try_into().expect("8 bytes"));
        let total = usize::try_from(len)
            .ok()
            .and_then(|l| l.checked_add(9))
            .filter(|&t| t <= bytes.len())
            .ok_or_else(|| invalid("summary record longer than the summary"))?;
        records.push((bytes[0], &bytes[..total]));
        bytes = &bytes[total..];
    }
    Ok(records)
}

/// The id (first body field, `u16`) of a Schema or Channel record.
fn record_id(record: &[u8]) -> u16 {
    record
        .get(9..11)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .unwrap_or(0)
}

/// Sorts the summary's Schema and Channel records of a finished MCAP file by
/// id and rewrites the footer's summary CRC.
pub(super) fn sort_summary(file: &mut File) -> std::io::Result<()> {
    let file_len = file.seek(SeekFrom::End(0))?;
    let footer_at = file_len
        .checked_sub(MAGIC_LEN + FOOTER_RECORD_LEN)
        .ok_or_else(|| invalid("file shorter than a footer"))?;
    let mut footer = [0u8; FOOTER_RECORD_LEN as usize];
    file.seek(SeekFrom::Start(footer_at))?;
    file.read_exact(&mut footer)?;
    if footer[0] != OP_FOOTER {
        return Err(invalid("no footer record before the end magic"));
    }
    let summary_start = u64::from_le_bytes(footer[9..17].try_into().expect("8 bytes"));
    let saved_crc = u32::from_le_bytes(footer[25..29].try_into().expect("4 bytes"));
    if summary_start == 0 || summary_start > footer_at {
        return Ok(()); // no summary section
    }
    let mut summary = vec![0u8; (footer_at - summary_start) as usize];
    file.seek(SeekFrom::Start(summary_start))?;
    file.read_exact(&mut summary)?;

    let records = split_records(&summary)?;
    let mut sorted = Vec::with_capacity(summary.len());
    let mut i = 0;
    while i < records.len() {
        let op = records[i].0;
        let end = if op == OP_SCHEMA || op == OP_CHANNEL {
            let run_len = records[i..].iter().take_while(|r| r.0 == op).count();
            i + run_len
        } else {
            i + 1
        };
        let mut run: Vec<&[u8]> = records[i..end].iter().map(|r| r.1).collect();
        if op == OP_SCHEMA || op == OP_CHANNEL {
            run.sort_by_key(|r| record_id(r));
        }
        for r in run {
            sorted.extend_from_slice(r);
        }
        i = end;
    }
    debug_assert_eq!(sorted.len(), summary.len());
    if sorted == summary {
        return Ok(());
    }
    file.seek(SeekFrom::Start(summary_start))?;
    file.write_all(&sorted)?;
    if saved_crc != 0 {
        // The CRC covers the summary and the footer up to its CRC field.
        let mut hasher = crc32fast::Hasher::new();
        hasher.update(&sorted);
        hasher.update(&footer[..25]);
        file.seek(SeekFrom::Start(footer_at + 25))?;
        file.write_all(&hasher.finalize().to_le_bytes())?;
    }
    file.flush()
}
