//! The one error type of the library. Every message says what is wrong and where
//! (file, mesh, primitive, accessor, vertex, key ...), so a technical artist can fix the asset.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file could not be read at all.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// An output file could not be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The input is malformed or violates the format's rules.
    #[error("{location}: {message}")]
    Invalid { location: String, message: String },
    /// The input is valid but uses something skinlet does not handle.
    #[error("{location}: unsupported: {message}")]
    Unsupported { location: String, message: String },
}

impl From<skinlet_runtime::Error> for Error {
    fn from(e: skinlet_runtime::Error) -> Self {
        match e {
            skinlet_runtime::Error::Invalid { location, message } => Error::Invalid { location, message },
            skinlet_runtime::Error::Unsupported { location, message } => Error::Unsupported { location, message },
        }
    }
}

impl Error {
    pub(crate) fn invalid(location: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Invalid { location: location.into(), message: message.into() }
    }
    pub(crate) fn unsupported(location: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Unsupported { location: location.into(), message: message.into() }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
