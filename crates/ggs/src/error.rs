//! Error type of the library.
//!
//! Every error that concerns a file names the file and, where it applies, the line or byte
//! offset and what was expected, so that a user can fix the input without a debugger.

use std::path::PathBuf;

/// All failures of the ggs library.
#[derive(Debug, thiserror::Error)]
pub enum GgsError {
    /// The file could not be opened or read at the operating-system level.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file was read but its content is malformed: `message` says what was found and
    /// what was expected there.
    #[error("{path}: {location}{message}")]
    Parse {
        path: PathBuf,
        /// Where in the file: a line, a byte offset, or the file as a whole.
        location: Location,
        message: String,
    },
    /// The file extension (or `--format`) names no format that ggs reads or writes.
    #[error(
        "{path}: unknown point-cloud format {what} (known: ply, pcd, xyz, txt, csv, pts, npy, npz, bin, las, laz, e57, obj, stl)"
    )]
    UnknownFormat { path: PathBuf, what: String },
    /// A cloud holds no usable point.
    #[error("{what}: the point cloud is empty{detail}")]
    EmptyCloud { what: String, detail: String },
    /// A parameter is out of its valid range.
    #[error("invalid parameter {name}: {message}")]
    InvalidParameter { name: &'static str, message: String },
    /// A setting given in a settings file, on the command line or as a keyword argument is
    /// unknown, of the wrong kind or out of its range: `origin` says where it was given.
    #[error("{origin}: setting {key}: {message}")]
    Setting {
        origin: String,
        key: String,
        message: String,
    },
    /// The search would need more memory than the budget allows.
    #[error("{0}")]
    MemoryBudget(String),
    /// The search was cancelled by the caller.
    #[error("the search was cancelled")]
    Cancelled,
}

impl GgsError {
    /// A parse error at a line (1-based).
    pub fn at_line(path: &std::path::Path, line: usize, message: impl Into<String>) -> Self {
        GgsError::Parse {
            path: path.to_path_buf(),
            location: Location::Line(line),
            message: message.into(),
        }
    }

    /// A parse error at a byte offset.
    pub fn at_byte(path: &std::path::Path, offset: u64, message: impl Into<String>) -> Self {
        GgsError::Parse {
            path: path.to_path_buf(),
            location: Location::Byte(offset),
            message: message.into(),
        }
    }

    /// A parse error at a location.
    pub fn at(path: &std::path::Path, location: Location, message: impl Into<String>) -> Self {
        GgsError::Parse {
            path: path.to_path_buf(),
            location,
            message: message.into(),
        }
    }

    /// A parse error that concerns the file as a whole.
    pub fn in_file(path: &std::path::Path, message: impl Into<String>) -> Self {
        GgsError::Parse {
            path: path.to_path_buf(),
            location: Location::File,
            message: message.into(),
        }
    }

    /// An I/O error on a file.
    pub fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        GgsError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// A parameter error.
    pub fn param(name: &'static str, message: impl Into<String>) -> Self {
        GgsError::InvalidParameter {
            name,
            message: message.into(),
        }
    }
}

/// Where in a file a parse error is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// The file as a whole (a count that does not match, a missing header field).
    File,
    /// A 1-based line of a text file or header.
    Line(usize),
    /// A 0-based byte offset from the start of the file.
    Byte(u64),
}

impl std::fmt::Display for Location {
    /// `"line 12: "`, `"byte 4096: "`, or nothing for the whole file.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Location::File => Ok(()),
            Location::Line(l) => write!(f, "line {l}: "),
            Location::Byte(b) => write!(f, "byte {b}: "),
        }
    }
}

impl GgsError {
    /// The location of a parse error, if this is one.
    pub fn location(&self) -> Option<Location> {
        match self {
            GgsError::Parse { location, .. } => Some(*location),
            _ => None,
        }
    }
}

/// Result alias of the library.
pub type Result<T> = std::result::Result<T, GgsError>;
