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
    /// The file was read but its content is malformed.
    #[error("{path}: {location}{message}")]
    Parse {
        path: PathBuf,
        /// "line 12: ", "byte 4096: " or empty.
        location: String,
        message: String,
    },
    /// The file extension (or `--format`) names no format that ggs reads or writes.
    #[error(
        "{path}: unknown point-cloud format {what} (known: ply, pcd, xyz, txt, csv, pts, npy)"
    )]
    UnknownFormat { path: PathBuf, what: String },
    /// A cloud holds no usable point.
    #[error("{what}: the point cloud is empty{detail}")]
    EmptyCloud { what: String, detail: String },
    /// A parameter is out of its valid range.
    #[error("invalid parameter {name}: {message}")]
    InvalidParameter { name: &'static str, message: String },
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
            location: format!("line {line}: "),
            message: message.into(),
        }
    }

    /// A parse error at a byte offset.
    pub fn at_byte(path: &std::path::Path, offset: u64, message: impl Into<String>) -> Self {
        GgsError::Parse {
            path: path.to_path_buf(),
            location: format!("byte {offset}: "),
            message: message.into(),
        }
    }

    /// A parse error that concerns the file as a whole.
    pub fn in_file(path: &std::path::Path, message: impl Into<String>) -> Self {
        GgsError::Parse {
            path: path.to_path_buf(),
            location: String::new(),
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

/// Result alias of the library.
pub type Result<T> = std::result::Result<T, GgsError>;
