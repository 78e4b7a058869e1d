//! The MCAP container: records read from the file in order, chunks
//! decompressed and checked, with memory bounded by what the file holds.
//!
//! The outer record stream comes from the `mcap` crate's sans-io reader,
//! which checks the data-section and summary CRCs. Chunks are decompressed
//! here rather than by that reader: in `mcap` 0.24 its streaming decompression
//! loops forever when a corrupt zstd frame asks for more input after the
//! chunk's compressed bytes are used up (no progress check in
//! `decompress_inner`), which a byte flip inside a chunk triggers. One-shot
//! decompression with the chunk's declared size as the output capacity cannot
//! loop, and the chunk CRC is checked before any record in it is used.

use crate::DatasetError;
use mcap::records::{ChunkHeader, Record};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use std::borrow::Cow;
use std::fs::File;
use std::io::Read;
use std::path::Path;

/// Bytes handed to the MCAP reader per read call: memory grows with what the
/// file really holds, never with a length field of a corrupt record.
const READ_BLOCK: usize = 1 << 20;

/// Upper bound of a decompressed chunk relative to the file size (zstd
/// rarely compresses sensor data 64-fold), so that a corrupt size field
/// cannot make the reader allocate gigabytes.
fn decompressed_limit(file_len: u64) -> usize {
    let limit = file_len.saturating_mul(64).max(64 << 20);
    usize::try_from(limit).unwrap_or(usize::MAX)
}

/// Runs `on_record` for every record of the file, the records inside chunks
/// included (the Chunk records themselves are not passed on).
pub(super) fn for_each_record(
    path: &Path,
    mut file: File,
    file_len: u64,
    mut on_record: impl FnMut(Record<'_>) -> Result<(), DatasetError>,
) -> Result<(), DatasetError> {
    let record_limit = usize::try_from(file_len).unwrap_or(usize::MAX);
    let options = LinearReaderOptions::default()
        .with_emit_chunks(true)
        .with_validate_data_section_crc(true)
        .with_validate_summary_section_crc(true)
        .with_record_length_limit(record_limit);
    let mut reader = LinearReader::new_with_options(options);
    let mut records = 0u64;
    let error = |records: u64, err: &dyn std::fmt::Display| DatasetError::Format {
        path: path.to_path_buf(),
        message: format!(
            "corrupt or truncated MCAP at record {records} (counted from 0, inside chunks too): {err}"
        ),
    };
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| error(records, &e))? {
            LinearReadEvent::ReadRequest(need) => {
                let buf = reader.insert(need.clamp(1, READ_BLOCK));
                let n = read_some(&mut file, buf).map_err(|e| DatasetError::io(path, e))?;
                reader.notify_read(n);
            }
            LinearReadEvent::Record { data, opcode } => {
                match mcap::parse_record(opcode, data).map_err(|e| error(records, &e))? {
                    Record::Chunk { header, data } => {
                        let content = decompress(&header, &data, decompressed_limit(file_len))
                            .map_err(|e| error(records, &e))?;
                        records += 1;
                        for inner in mcap::read::LinearReader::sans_magic(&content) {
                            on_record(inner.map_err(|e| error(records, &e))?)?;
                            records += 1;
                        }
                    }
                    record => {
                        on_record(record)?;
                        records += 1;
                    }
                }
            }
        }
    }
    Ok(())
}

/// The records of one chunk, decompressed and checked against its CRC.
fn decompress<'a>(
    header: &ChunkHeader,
    data: &'a [u8],
    limit: usize,
) -> Result<Cow<'a, [u8]>, String> {
    let size = usize::try_from(header.uncompressed_size)
        .ok()
        .filter(|&s| s <= limit)
        .ok_or_else(|| {
            format!(
                "chunk declares {} uncompressed bytes, more than the {limit} allowed for this file",
                header.uncompressed_size
            )
        })?;
    let content: Cow<[u8]> = match header.compression.as_str() {
        "" => Cow::Borrowed(data),
        "zstd" => {
            Cow::Owned(zstd::bulk::decompress(data, size).map_err(|e| format!("zstd chunk: {e}"))?)
        }
        "lz4" => {
            let mut out = Vec::with_capacity(size);
            lz4::Decoder::new(data)
                .and_then(|d| d.take(size as u64 + 1).read_to_end(&mut out))
                .map_err(|e| format!("lz4 chunk: {e}"))?;
            Cow::Owned(out)
        }
        other => return Err(format!("unsupported chunk compression `{other}`")),
    };
    if content.len() != size {
        return Err(format!(
            "chunk holds {} bytes once decompressed, its header says {size}",
            content.len()
        ));
    }
    if header.uncompressed_crc != 0 {
        let crc = crc32fast::hash(&content);
        if crc != header.uncompressed_crc {
            return Err(format!(
                "chunk CRC mismatch (stored {:08x}, computed {crc:08x})",
                header.uncompressed_crc
            ));
        }
    }
    Ok(content)
}

fn read_some(file: &mut File, buf: &mut [u8]) -> std::io::Result<usize> {
    loop {
        match file.read(buf) {
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            other => return other,
        }
    }
}
