//! Ingest errors. Each names the input file and, where it applies, the record index, the byte
//! offset and the field, plus what was expected.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    #[error("{file}: {source}")]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: {source}")]
    Record {
        file: PathBuf,
        #[source]
        source: crate::tfrecord::RecordError,
    },
    #[error("{file}: empty input: no TFRecord records (expected Waymo Frame or WOMD Scenario records)")]
    Empty { file: PathBuf },
    #[error("{file}: record {index} (byte {offset}) is neither a Waymo v1 Frame nor a WOMD Scenario ({detail})")]
    Unrecognised { file: PathBuf, index: usize, offset: u64, detail: String },
    #[error("{file}: record {index}: `{field}`: {message}")]
    Invalid { file: PathBuf, index: usize, field: String, message: String },
    #[error("{file}: holds {found} records but the other inputs hold {expected} records; ingest one kind at a time")]
    MixedKinds { file: PathBuf, found: &'static str, expected: &'static str },
    #[error("duplicate frame timestamp {timestamp_micros} us: {first} and {second}")]
    DuplicateTimestamp { timestamp_micros: i64, first: String, second: String },
    #[error("{file}: line {line}: {message}")]
    Line { file: PathBuf, line: usize, message: String },
    #[error("{file}: `{field}`: {message}")]
    Field { file: PathBuf, field: String, message: String },
    #[error("{file}: {message}")]
    Content { file: PathBuf, message: String },
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
}

/// Shorthand for a content error at a field of a record.
pub(crate) fn invalid(
    file: &std::path::Path,
    index: usize,
    field: impl Into<String>,
    message: impl Into<String>,
) -> IngestError {
    IngestError::Invalid { file: file.to_path_buf(), index, field: field.into(), message: message.into() }
}

/// Shorthand for a problem with a whole file or folder (missing image, count mismatch).
pub(crate) fn content(file: impl Into<PathBuf>, message: impl Into<String>) -> IngestError {
    IngestError::Content { file: file.into(), message: message.into() }
}
