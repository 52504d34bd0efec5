//! Errors of the export crate. Reading errors name the element path and attribute
//! (`OpenSCENARIO/Storyboard/.../Vertex[3]@time`) and say what was expected; writing errors name
//! the field of the case that cannot be exported.

use scene::SceneError;

#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The executed case does not validate (`Executed::validate`).
    #[error("the executed case is not valid: at `{field}`: {message}")]
    InvalidCase { field: String, message: String },
    /// The executed case was made in another scene.
    #[error("the executed case is for scene `{executed}` but the scene given is `{scene}`")]
    WrongScene { executed: String, scene: String },
    /// A value to export is not a finite number.
    #[error("cannot export `{what}`: {value} is not a finite number")]
    NotFinite { what: String, value: f64 },
    /// The input is larger than a writer's budget (`xodr::budget`): refused before writing.
    #[error("cannot export `{what}`: {count} {unit}, more than the {max} a file may hold")]
    TooLarge { what: String, count: usize, unit: &'static str, max: usize },
    /// A value to export is outside the range the writer accepts.
    #[error("cannot export `{what}`: {message}")]
    OutOfRange { what: String, message: String },
    /// An option of a writer is out of range.
    #[error("option `{field}`: {message}")]
    BadOption { field: &'static str, message: String },
    /// The XML is not well-formed (syntax error, mismatched tags, bad attribute).
    #[error("XML error in `{path}` at byte {offset}: {message}")]
    Xml { path: String, offset: u64, message: String },
    /// The document ends while elements are still open.
    #[error("unexpected end of the document inside `{path}` (opened at byte {offset}): the file is truncated")]
    Truncated { path: String, offset: u64 },
    /// Well-formed XML whose content is not what the reader expects.
    #[error("at `{path}`: {message}")]
    Content { path: String, message: String },
    /// Serialising the XML failed.
    #[error("writing XML: {0}")]
    Write(#[source] std::io::Error),
    /// Writing the file failed.
    #[error(transparent)]
    Scene(#[from] SceneError),
}
