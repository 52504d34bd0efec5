//! TFRecord framing: `u64 LE length`, `masked CRC-32C(length bytes)`, `data`,
//! `masked CRC-32C(data)`, with `masked(c) = ((c >> 15) | (c << 17)) + 0xa282ead8 (mod 2^32)`.
//!
//! Both checksums are verified on every record. A file that ends inside a record is an error
//! (never a silently dropped last record); every error names the record index and the byte
//! offset where that record starts.

use std::io::{self, Read, Write};

const MASK_DELTA: u32 = 0xa282_ead8;

/// The masked CRC-32C TFRecord stores.
pub fn masked_crc32c(bytes: &[u8]) -> u32 {
    let c = crc32c::crc32c(bytes);
    c.rotate_right(15).wrapping_add(MASK_DELTA)
}

/// What went wrong inside one record.
#[derive(Debug, thiserror::Error)]
pub enum RecordFault {
    #[error("file ends inside the record's {0} (truncated file)")]
    Truncated(&'static str),
    #[error("length CRC mismatch (stored {stored:#010x}, computed {computed:#010x}): corrupt length field")]
    LengthCrc { stored: u32, computed: u32 },
    #[error("data CRC mismatch (stored {stored:#010x}, computed {computed:#010x}): corrupt record data")]
    DataCrc { stored: u32, computed: u32 },
    #[error("read failed: {0}")]
    Io(#[from] io::Error),
}

/// A record fault with its position.
#[derive(Debug, thiserror::Error)]
#[error("record {index} (starting at byte {offset}): {fault}")]
pub struct RecordError {
    pub index: usize,
    pub offset: u64,
    #[source]
    pub fault: RecordFault,
}

/// One record's payload and position.
#[derive(Debug, Clone)]
pub struct Record {
    pub index: usize,
    pub offset: u64,
    pub data: Vec<u8>,
}

/// Streaming reader over TFRecord framing. Stops after the first error.
pub struct TfRecordReader<R> {
    inner: R,
    index: usize,
    offset: u64,
    failed: bool,
}

impl<R: Read> TfRecordReader<R> {
    pub fn new(inner: R) -> Self {
        Self { inner, index: 0, offset: 0, failed: false }
    }

    /// Reads exactly `buf.len()` bytes; `Ok(n)` with `n < len` only at end of input.
    fn fill(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let mut n = 0;
        while n < buf.len() {
            match self.inner.read(&mut buf[n..]) {
                Ok(0) => break,
                Ok(k) => n += k,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(n)
    }

    fn read_record(&mut self) -> Result<Option<Vec<u8>>, RecordFault> {
        let mut len_bytes = [0u8; 8];
        match self.fill(&mut len_bytes)? {
            0 => return Ok(None),
            8 => {}
            _ => return Err(RecordFault::Truncated("length field")),
        }
        let mut crc = [0u8; 4];
        if self.fill(&mut crc)? != 4 {
            return Err(RecordFault::Truncated("length CRC"));
        }
        let (stored, computed) = (u32::from_le_bytes(crc), masked_crc32c(&len_bytes));
        if stored != computed {
            return Err(RecordFault::LengthCrc { stored, computed });
        }
        let len = u64::from_le_bytes(len_bytes);
        // Read through `take` so a huge (but CRC-valid) length cannot allocate beyond the input.
        let mut data = Vec::new();
        (&mut self.inner).take(len).read_to_end(&mut data)?;
        if (data.len() as u64) < len {
            return Err(RecordFault::Truncated("data"));
        }
        if self.fill(&mut crc)? != 4 {
            return Err(RecordFault::Truncated("data CRC"));
        }
        let (stored, computed) = (u32::from_le_bytes(crc), masked_crc32c(&data));
        if stored != computed {
            return Err(RecordFault::DataCrc { stored, computed });
        }
        Ok(Some(data))
    }
}

impl<R: Read> Iterator for TfRecordReader<R> {
    type Item = Result<Record, RecordError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let (index, offset) = (self.index, self.offset);
        match self.read_record() {
            Ok(None) => None,
            Ok(Some(data)) => {
                self.index += 1;
                self.offset += 16 + data.len() as u64;
                Some(Ok(Record { index, offset, data }))
            }
            Err(fault) => {
                self.failed = true;
                Some(Err(RecordError { index, offset, fault }))
            }
        }
    }
}

/// Writes one record with TFRecord framing.
pub fn write_record<W: Write>(out: &mut W, data: &[u8]) -> io::Result<()> {
    let len = (data.len() as u64).to_le_bytes();
    out.write_all(&len)?;
    out.write_all(&masked_crc32c(&len).to_le_bytes())?;
    out.write_all(data)?;
    out.write_all(&masked_crc32c(data).to_le_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn framed(records: &[&[u8]]) -> Vec<u8> {
        let mut out = Vec::new();
        for r in records {
            write_record(&mut out, r).unwrap();
        }
        out
    }

    fn read_all(bytes: &[u8]) -> Vec<Result<Record, RecordError>> {
        TfRecordReader::new(bytes).collect()
    }

    #[test]
    fn crc32c_known_value() {
        // CRC-32C check value of "123456789" is 0xe3069283 (RFC 3720 B.4).
        assert_eq!(crc32c::crc32c(b"123456789"), 0xe306_9283);
    }

    #[test]
    fn round_trip_with_offsets() {
        let bytes = framed(&[b"abc", b"", b"hello world"]);
        let recs: Vec<Record> = read_all(&bytes).into_iter().map(Result::unwrap).collect();
        assert_eq!(recs.len(), 3);
        assert_eq!(recs[0].offset, 0);
        assert_eq!(recs[1].offset, 19);
        assert_eq!(recs[2].offset, 35);
        assert_eq!(recs[2].data, b"hello world");
    }

    #[test]
    fn every_truncation_point_is_an_error() {
        let bytes = framed(&[b"first", b"second record"]);
        let first_len = 16 + 5;
        for cut in first_len + 1..bytes.len() {
            let res = read_all(&bytes[..cut]);
            assert_eq!(res.len(), 2, "cut at {cut}");
            let err = res[1].as_ref().unwrap_err();
            assert_eq!((err.index, err.offset), (1, first_len as u64));
            assert!(matches!(err.fault, RecordFault::Truncated(_)), "cut at {cut}: {err}");
        }
    }

    #[test]
    fn every_flipped_bit_is_caught() {
        let bytes = framed(&[b"payload!"]);
        for i in 0..bytes.len() {
            let mut bad = bytes.clone();
            bad[i] ^= 0x10;
            let res = read_all(&bad);
            assert!(res.iter().any(|r| r.is_err()), "flip at byte {i} not caught");
        }
    }
}
