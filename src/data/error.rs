use std::fmt;

/// A file that could not be read as what it claims to be: names the file, where in it
/// (line, or byte offset for binary formats) and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct FormatError {
    pub file: String,
    pub location: Option<Location>,
    pub message: String,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Location {
    Line(usize),
    Byte(usize),
}

impl FormatError {
    pub fn new(file: impl Into<String>, message: impl Into<String>) -> Self {
        Self { file: file.into(), location: None, message: message.into() }
    }

    pub fn at_line(file: impl Into<String>, line: usize, message: impl Into<String>) -> Self {
        Self { file: file.into(), location: Some(Location::Line(line)), message: message.into() }
    }

    pub fn at_byte(file: impl Into<String>, byte: usize, message: impl Into<String>) -> Self {
        Self { file: file.into(), location: Some(Location::Byte(byte)), message: message.into() }
    }
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.location {
            Some(Location::Line(l)) => write!(f, "{}:{}: {}", self.file, l, self.message),
            Some(Location::Byte(b)) => write!(f, "{} (byte {}): {}", self.file, b, self.message),
            None => write!(f, "{}: {}", self.file, self.message),
        }
    }
}

impl std::error::Error for FormatError {}
