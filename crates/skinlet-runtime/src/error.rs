//! The runtime's error type: what is wrong and where, for data a caller hands over (camera
//! parameters, bounds, boxes, envelope ranges).

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Error {
    /// The data is malformed or inconsistent.
    Invalid { location: String, message: String },
    /// The data is valid but of a kind this runtime does not read (a newer bake version).
    Unsupported { location: String, message: String },
}

impl Error {
    pub(crate) fn invalid(location: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Invalid { location: location.into(), message: message.into() }
    }
    pub(crate) fn unsupported(location: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Unsupported { location: location.into(), message: message.into() }
    }
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Error::Invalid { location, message } => write!(f, "{location}: {message}"),
            Error::Unsupported { location, message } => write!(f, "{location}: unsupported: {message}"),
        }
    }
}

impl std::error::Error for Error {}

pub type Result<T, E = Error> = std::result::Result<T, E>;
