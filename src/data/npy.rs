//! NumPy `.npy` arrays of floats: read (versions 1.0, 2.0 and 3.0; `<f4` or `<f8`, C order)
//! and write (version 1.0, `<f4`), plus motions as `(frames, joints, 3)` position arrays.
//!
//! Errors name the file and the byte offset of the problem; no input makes the reader panic.

use std::sync::Arc;

use glam::Vec3;

use super::FormatError;
use crate::motion::{Motion, Skeleton};

const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// A float array: `data` holds the elements in C (row-major) order.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    pub shape: Vec<usize>,
    pub data: Vec<f32>,
}

#[derive(Clone, Copy, PartialEq)]
enum Dtype {
    F4,
    F8,
}

/// Reads an `.npy` file's bytes. `<f8` data is converted to `f32`.
pub fn read_npy(bytes: &[u8], file: &str) -> Result<NpyArray, FormatError> {
    read_npy_located(bytes, file).map(|(a, _, _)| a)
}

/// The array, the byte offset where its data starts and the size of one stored element.
fn read_npy_located(bytes: &[u8], file: &str) -> Result<(NpyArray, usize, usize), FormatError> {
    let err = |at: usize, msg: String| FormatError::at_byte(file, at, msg);
    if bytes.is_empty() {
        return Err(err(0, "empty file: expected an NPY array".into()));
    }
    if let Some(at) = (0..6).find(|&i| bytes.get(i) != Some(&MAGIC[i])) {
        if at < bytes.len() {
            return Err(err(at, "bad magic: not an NPY file (expected it to start with \\x93NUMPY)".into()));
        }
        return Err(err(bytes.len(), "file ends inside the NPY magic string".into()));
    }
    if bytes.len() < 8 {
        return Err(err(bytes.len(), "file ends inside the NPY version".into()));
    }
    let (major, minor) = (bytes[6], bytes[7]);
    let len_size = match (major, minor) {
        (1, 0) => 2,
        (2, 0) | (3, 0) => 4,
        _ => return Err(err(6, format!("unsupported NPY version {major}.{minor} (1.0, 2.0 and 3.0 are)"))),
    };
    let header_start = 8 + len_size;
    if bytes.len() < header_start {
        return Err(err(bytes.len(), "file ends inside the header length".into()));
    }
    let header_len = if len_size == 2 {
        u16::from_le_bytes([bytes[8], bytes[9]]) as usize
    } else {
        u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize
    };
    let data_start = header_start.saturating_add(header_len);
    if bytes.len() < data_start {
        return Err(err(
            bytes.len(),
            format!(
                "truncated header: it declares {header_len} bytes from byte {header_start}, the file has {}",
                bytes.len() - header_start
            ),
        ));
    }
    let header = &bytes[header_start..data_start];
    if major == 3 {
        if let Err(e) = std::str::from_utf8(header) {
            return Err(err(header_start + e.valid_up_to(), "header is not UTF-8".into()));
        }
    }
    let fields = HeaderParser { bytes: header, pos: 0, base: header_start, file }.dict()?;

    let field = |name: &str| fields.iter().find(|(k, _, _)| k == name);
    let missing = |name: &str| err(header_start, format!("header has no '{name}' entry"));
    let (_, descr_at, descr) = field("descr").ok_or_else(|| missing("descr"))?;
    let dtype = match descr {
        Value::Str(s) => match s.as_str() {
            "<f4" => Dtype::F4,
            "<f8" => Dtype::F8,
            ">f4" | ">f8" => {
                return Err(err(*descr_at, format!("big-endian data ('{s}') is not supported; save little-endian ('<f4' or '<f8')")))
            }
            other => return Err(err(*descr_at, format!("dtype '{}' is not supported (only '<f4' and '<f8')", clip(other)))),
        },
        _ => return Err(err(*descr_at, "structured dtypes are not supported (only '<f4' and '<f8')".into())),
    };
    let (_, shape_at, shape) = field("shape").ok_or_else(|| missing("shape"))?;
    let shape: Vec<usize> = match shape {
        Value::Seq(items) => items
            .iter()
            .map(|v| match v {
                Value::Int(i) => usize::try_from(*i).map_err(|_| err(*shape_at, format!("shape entry {i} is too large"))),
                _ => Err(err(*shape_at, "shape must be a tuple of integers".into())),
            })
            .collect::<Result<_, _>>()?,
        _ => return Err(err(*shape_at, "shape must be a tuple of integers".into())),
    };
    let (_, fortran_at, fortran) = field("fortran_order").ok_or_else(|| missing("fortran_order"))?;
    match fortran {
        Value::Bool(false) => {}
        // One axis (or none) longer than 1: Fortran and C order store the same bytes.
        Value::Bool(true) if shape.iter().filter(|&&d| d > 1).count() <= 1 => {}
        Value::Bool(true) => {
            return Err(err(*fortran_at, "Fortran-order arrays are not supported; save in C order (np.ascontiguousarray)".into()))
        }
        _ => return Err(err(*fortran_at, "fortran_order must be True or False".into())),
    }

    let count = shape.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
    let item = if dtype == Dtype::F4 { 4 } else { 8 };
    let Some(need) = count.and_then(|c| c.checked_mul(item)) else {
        return Err(err(*shape_at, format!("shape {} is too large", shape_text(&shape))));
    };
    let have = bytes.len() - data_start;
    if have < need {
        return Err(err(
            bytes.len(),
            format!(
                "truncated data: shape {} of {} needs {need} bytes after the header (which ends at byte {data_start}), the file has {have}",
                shape_text(&shape),
                if dtype == Dtype::F4 { "<f4" } else { "<f8" }
            ),
        ));
    }
    if have > need {
        return Err(err(data_start + need, format!("{} unexpected bytes after the data of shape {}", have - need, shape_text(&shape))));
    }
    let raw = &bytes[data_start..];
    let data = match dtype {
        Dtype::F4 => raw.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect(),
        Dtype::F8 => raw.chunks_exact(8).map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]) as f32).collect(),
    };
    Ok((NpyArray { shape, data }, data_start, item))
}

/// An `.npy` file (version 1.0, `<f4`, C order) holding `data` with `shape`; the header is
/// padded with spaces so the data starts at a multiple of 64 bytes, and ends with a newline.
/// Falls back to version 2.0 only when the header would not fit in 65535 bytes.
///
/// Panics if `data.len()` is not the product of `shape` (a programming error).
pub fn write_npy(shape: &[usize], data: &[f32]) -> Vec<u8> {
    let count: usize = shape.iter().product();
    assert_eq!(count, data.len(), "write_npy: shape {} holds {count} values, got {}", shape_text(shape), data.len());
    let dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {}, }}", shape_text(shape));
    let (version, len_size) = if 10 + dict.len() + 64 <= u16::MAX as usize { (1u8, 2usize) } else { (2u8, 4usize) };
    let unpadded = 8 + len_size + dict.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    let header_len = dict.len() + pad + 1;
    let mut out = Vec::with_capacity(8 + len_size + header_len + 4 * data.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[version, 0]);
    if len_size == 2 {
        out.extend_from_slice(&(header_len as u16).to_le_bytes());
    } else {
        out.extend_from_slice(&(header_len as u32).to_le_bytes());
    }
    out.extend_from_slice(dict.as_bytes());
    out.extend(std::iter::repeat_n(b' ', pad));
    out.push(b'\n');
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// The motion's world positions as an `(frames, joints, 3)` `<f4` array.
pub fn motion_to_npy(m: &Motion) -> Vec<u8> {
    let data: Vec<f32> = m.positions().iter().flat_map(|p| p.to_array()).collect();
    write_npy(&[m.frames(), m.joints(), 3], &data)
}

/// A motion from an `(frames, joints, 3)` position array on `skeleton`. The joint count must
/// match the skeleton's, `fps` must be positive and every value finite.
pub fn motion_from_npy(bytes: &[u8], file: &str, skeleton: Arc<Skeleton>, fps: f32) -> Result<Motion, FormatError> {
    if !(fps.is_finite() && fps > 0.0) {
        return Err(FormatError::new(file, format!("fps must be positive, got {fps}")));
    }
    if skeleton.is_empty() {
        return Err(FormatError::new(file, "the skeleton has no joints"));
    }
    let (array, data_start, item) = read_npy_located(bytes, file)?;
    let j = skeleton.len();
    match array.shape.as_slice() {
        [_, jj, 3] if *jj == j => {}
        _ => {
            return Err(FormatError::at_byte(
                file,
                8,
                format!("array has shape {}; expected (frames, {j}, 3) for a skeleton of {j} joints", shape_text(&array.shape)),
            ))
        }
    }
    if let Some(k) = array.data.iter().position(|v| !v.is_finite()) {
        return Err(FormatError::at_byte(
            file,
            data_start + item * k,
            format!("value {} (frame {}, joint {}) is not finite", k, k / (3 * j), k / 3 % j),
        ));
    }
    let positions = array.data.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
    Ok(Motion::from_positions(skeleton, fps, positions))
}

fn shape_text(shape: &[usize]) -> String {
    match shape {
        [] => "()".into(),
        [d] => format!("({d},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    }
}

fn clip(s: &str) -> String {
    if s.chars().count() <= 32 {
        s.to_string()
    } else {
        format!("{}...", s.chars().take(32).collect::<String>())
    }
}

/// A Python literal in the header.
#[derive(Debug)]
enum Value {
    Str(String),
    Bool(bool),
    None,
    Int(u64),
    Seq(Vec<Value>),
}

/// Parses the header's Python dict literal: `{'key': value, ...}` followed by spaces and a
/// newline. Keys are strings; values strings, True/False/None, non-negative integers, or
/// tuples/lists of those (nested at most 16 deep).
struct HeaderParser<'a> {
    bytes: &'a [u8],
    pos: usize,
    base: usize,
    file: &'a str,
}

impl HeaderParser<'_> {
    fn err(&self, msg: impl Into<String>) -> FormatError {
        FormatError::at_byte(self.file, self.base + self.pos, format!("bad NPY header: {}", msg.into()))
    }

    fn ws(&mut self) {
        while self.pos < self.bytes.len() && matches!(self.bytes[self.pos], b' ' | b'\t' | b'\n' | b'\r') {
            self.pos += 1;
        }
    }

    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    fn expect(&mut self, c: u8) -> Result<(), FormatError> {
        self.ws();
        if self.peek() == Some(c) {
            self.pos += 1;
            Ok(())
        } else {
            Err(self.err(format!("expected '{}', found {}", c as char, self.found())))
        }
    }

    fn found(&self) -> String {
        match self.peek() {
            None => "the end of the header".into(),
            Some(c) if c.is_ascii_graphic() => format!("'{}'", c as char),
            Some(c) => format!("byte 0x{c:02x}"),
        }
    }

    /// (key, absolute byte offset of the value, value) for each entry.
    fn dict(&mut self) -> Result<Vec<(String, usize, Value)>, FormatError> {
        self.expect(b'{')?;
        let mut out = Vec::new();
        loop {
            self.ws();
            if self.peek() == Some(b'}') {
                self.pos += 1;
                break;
            }
            let key = match self.value(0)? {
                Value::Str(s) => s,
                _ => return Err(self.err("dictionary keys must be strings")),
            };
            self.expect(b':')?;
            self.ws();
            let at = self.base + self.pos;
            let value = self.value(0)?;
            out.push((key, at, value));
            self.ws();
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b'}') => {}
                _ => return Err(self.err(format!("expected ',' or '}}', found {}", self.found()))),
            }
        }
        self.ws();
        if self.pos < self.bytes.len() {
            return Err(self.err(format!("unexpected {} after the dictionary", self.found())));
        }
        Ok(out)
    }

    fn value(&mut self, depth: usize) -> Result<Value, FormatError> {
        self.ws();
        if depth > 16 {
            return Err(self.err("nested too deep"));
        }
        match self.peek() {
            Some(q @ (b'\'' | b'"')) => {
                self.pos += 1;
                let start = self.pos;
                while self.pos < self.bytes.len() && self.bytes[self.pos] != q {
                    if self.bytes[self.pos] == b'\\' {
                        self.pos += 1;
                    }
                    self.pos += 1;
                }
                if self.pos >= self.bytes.len() {
                    self.pos = start - 1;
                    return Err(self.err("unterminated string"));
                }
                let s = String::from_utf8_lossy(&self.bytes[start..self.pos]).into_owned();
                self.pos += 1;
                Ok(Value::Str(s))
            }
            Some(open @ (b'(' | b'[')) => {
                let close = if open == b'(' { b')' } else { b']' };
                self.pos += 1;
                let mut items = Vec::new();
                loop {
                    self.ws();
                    if self.peek() == Some(close) {
                        self.pos += 1;
                        return Ok(Value::Seq(items));
                    }
                    items.push(self.value(depth + 1)?);
                    self.ws();
                    match self.peek() {
                        Some(b',') => self.pos += 1,
                        Some(c) if c == close => {}
                        _ => return Err(self.err(format!("expected ',' or '{}', found {}", close as char, self.found()))),
                    }
                }
            }
            Some(b'0'..=b'9') => {
                let start = self.pos;
                while self.peek().is_some_and(|c| c.is_ascii_digit()) {
                    self.pos += 1;
                }
                let text = std::str::from_utf8(&self.bytes[start..self.pos]).unwrap_or("");
                let v = text.parse().map_err(|_| {
                    self.pos = start;
                    self.err(format!("integer {} is too large", clip(text)))
                });
                // Python 2 headers may write longs as `3L`.
                if self.peek() == Some(b'L') {
                    self.pos += 1;
                }
                v.map(Value::Int)
            }
            Some(c) if c.is_ascii_alphabetic() => {
                let start = self.pos;
                while self.peek().is_some_and(|c| c.is_ascii_alphanumeric() || c == b'_') {
                    self.pos += 1;
                }
                match &self.bytes[start..self.pos] {
                    b"True" => Ok(Value::Bool(true)),
                    b"False" => Ok(Value::Bool(false)),
                    b"None" => Ok(Value::None),
                    word => {
                        let word = String::from_utf8_lossy(word).into_owned();
                        self.pos = start;
                        Err(self.err(format!("unexpected '{}'", clip(&word))))
                    }
                }
            }
            _ => Err(self.err(format!("expected a value, found {}", self.found()))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Location;

    fn header(version: u8, dict: &str) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&[version, 0]);
        if version == 1 {
            out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
        } else {
            out.extend_from_slice(&(dict.len() as u32).to_le_bytes());
        }
        out.extend_from_slice(dict.as_bytes());
        out
    }

    fn err(bytes: &[u8]) -> FormatError {
        match read_npy(bytes, "x.npy") {
            Ok(a) => panic!("expected an error, read {:?}", a.shape),
            Err(e) => {
                assert_eq!(e.file, "x.npy");
                assert!(matches!(e.location, Some(Location::Byte(_))), "{e}");
                e
            }
        }
    }

    fn byte(e: &FormatError) -> usize {
        match e.location {
            Some(Location::Byte(b)) => b,
            _ => panic!("{e}"),
        }
    }

    #[test]
    fn write_read_round_trip_and_header_layout() {
        let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.5 - 3.0).collect();
        let bytes = write_npy(&[2, 4, 3], &data);
        let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
        assert_eq!((10 + header_len) % 64, 0);
        assert_eq!(bytes[10 + header_len - 1], b'\n');
        let text = std::str::from_utf8(&bytes[10..10 + header_len]).unwrap();
        assert!(text.starts_with("{'descr': '<f4', 'fortran_order': False, 'shape': (2, 4, 3), }"), "{text}");
        assert_eq!(bytes.len(), 10 + header_len + 96);
        let a = read_npy(&bytes, "x.npy").unwrap();
        assert_eq!(a, NpyArray { shape: vec![2, 4, 3], data });
        for shape in [vec![], vec![0], vec![5], vec![1, 0, 3]] {
            let n: usize = shape.iter().product();
            let a = read_npy(&write_npy(&shape, &vec![1.5; n]), "x.npy").unwrap();
            assert_eq!(a.shape, shape);
            assert_eq!(a.data.len(), n);
        }
    }

    #[test]
    fn reads_versions_2_and_3_and_f8() {
        let mut v2 = header(2, "{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }\n");
        for x in [1.0f64, -2.5, 1e300] {
            v2.extend_from_slice(&x.to_le_bytes());
        }
        let a = read_npy(&v2, "x.npy").unwrap();
        assert_eq!(a.shape, vec![3]);
        assert_eq!(&a.data[..2], &[1.0, -2.5]);
        assert!(a.data[2].is_infinite());
        // Version 3: UTF-8 header, double quotes, spacing, Python 2 long, key order.
        let mut v3 = header(3, "{\"shape\" : (2L,2) ,\"fortran_order\":False,'descr':'<f4'}   \n");
        for x in [1.0f32, 2.0, 3.0, 4.0] {
            v3.extend_from_slice(&x.to_le_bytes());
        }
        assert_eq!(read_npy(&v3, "x.npy").unwrap(), NpyArray { shape: vec![2, 2], data: vec![1.0, 2.0, 3.0, 4.0] });
    }

    #[test]
    fn fortran_big_endian_and_other_dtypes_are_errors() {
        let mut f = header(1, "{'descr': '<f4', 'fortran_order': True, 'shape': (2, 2), }\n");
        f.extend_from_slice(&[0; 16]);
        let e = err(&f);
        assert!(e.message.contains("Fortran"), "{e}");
        assert_eq!(byte(&e), 10 + "{'descr': '<f4', 'fortran_order': ".len());
        // A 1-D Fortran array is the same bytes: accepted.
        let mut f1 = header(1, "{'descr': '<f4', 'fortran_order': True, 'shape': (4,), }\n");
        f1.extend_from_slice(&[0; 16]);
        assert!(read_npy(&f1, "x.npy").is_ok());
        let mut be = header(1, "{'descr': '>f4', 'fortran_order': False, 'shape': (4,), }\n");
        be.extend_from_slice(&[0; 16]);
        let e = err(&be);
        assert!(e.message.contains("big-endian"), "{e}");
        assert_eq!(byte(&e), 10 + "{'descr': ".len());
        for d in ["<i4", "<f2", "|u1", "<c8", "O"] {
            let mut x = header(1, &format!("{{'descr': '{d}', 'fortran_order': False, 'shape': (4,), }}\n"));
            x.extend_from_slice(&[0; 64]);
            let e = err(&x);
            assert!(e.message.contains(&format!("dtype '{d}' is not supported")), "{e}");
        }
        let mut s = header(1, "{'descr': [('a', '<f4')], 'fortran_order': False, 'shape': (1,), }\n");
        s.extend_from_slice(&[0; 4]);
        assert!(err(&s).message.contains("structured"));
    }

    #[test]
    fn truncated_files_say_where() {
        let bytes = write_npy(&[3, 2], &[1.0; 6]);
        for cut in 0..bytes.len() {
            let e = err(&bytes[..cut]);
            assert!(byte(&e) <= cut, "{cut}: {e}");
        }
        let e = err(&bytes[..bytes.len() - 3]);
        assert!(e.message.contains("truncated data") && e.message.contains("needs 24 bytes"), "{e}");
        let e = err(&bytes[..20]);
        assert!(e.message.contains("truncated header"), "{e}");
        let mut long = bytes.clone();
        long.push(0);
        let e = err(&long);
        assert!(e.message.contains("1 unexpected bytes"), "{e}");
        assert_eq!(byte(&e), bytes.len());
    }

    #[test]
    fn empty_bad_magic_and_garbage_headers() {
        assert!(err(&[]).message.contains("empty"));
        let e = err(b"\x93NUMPX\x01\x00");
        assert!(e.message.contains("bad magic"));
        assert_eq!(byte(&e), 5);
        assert!(err(b"PK\x03\x04 a zip file").message.contains("bad magic"));
        let e = err(b"\x93NUMPY\x04\x00\x00\x00");
        assert!(e.message.contains("version 4.0"), "{e}");
        for (dict, want) in [
            ("{'descr': '<f4', 'fortran_order': False, 'shape': (2, x), }\n", "unexpected 'x'"),
            ("{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), \n", "expected a value"),
            ("{'descr': '<f4', 'fortran_order': False }\n", "no 'shape'"),
            ("{'descr': '<f4' 'fortran_order': False, 'shape': (1,), }\n", "expected ','"),
            ("{'descr': '<f4, 'fortran_order': False, 'shape': (1,), }\n", "expected ','"),
            ("{'descr' '<f4', 'fortran_order': False, 'shape': (1,), }\n", "expected ':'"),
            ("{'descr': '<f4', 'fortran_order': 0, 'shape': (1,), }\n", "fortran_order must be"),
            ("{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999999,), }\n", "too large"),
            ("{'descr': '<f4', 'fortran_order': False, 'shape': (4294967296, 4294967296, 4294967296), }\n", "too large"),
            ("{'descr': '<f4', 'fortran_order': False, 'shape': (1,), } trailing\n", "after the dictionary"),
            ("[1, 2]\n", "expected '{'"),
            ("{'descr': '<f4', 'shape': ((((((((((((((((((((1,),),),),),),),),),),),),),),),),),),),) }\n", "nested too deep"),
        ] {
            let mut b = header(1, dict);
            b.extend_from_slice(&[0; 4]);
            let e = err(&b);
            assert!(e.message.contains(want), "{dict}: {e}");
            assert!(byte(&e) >= 10, "{dict}: {e}");
        }
        let mut bad_utf8 = header(3, "{'descr': '<f4', 'fortran_order': False, 'shape': (1,), }\n");
        bad_utf8[12 + 11] = 0xff;
        let e = err(&bad_utf8);
        assert!(e.message.contains("UTF-8"), "{e}");
        assert_eq!(byte(&e), 23);
    }

    #[test]
    fn random_bytes_never_panic() {
        let mut state = 99u64;
        let valid = write_npy(&[2, 3], &[0.25; 6]);
        for i in 0..5000 {
            let mut b = valid.clone();
            for _ in 0..(i % 5 + 1) {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let at = (state >> 33) as usize % b.len();
                b[at] = (state >> 17) as u8;
            }
            if i % 7 == 0 {
                b.truncate((state >> 40) as usize % b.len());
            }
            if let Err(e) = read_npy(&b, "fuzz.npy") {
                assert_eq!(e.file, "fuzz.npy");
            }
        }
    }

    fn skeleton(j: usize) -> Arc<Skeleton> {
        Arc::new(
            Skeleton::new((0..j).map(|i| format!("j{i}")).collect(), (0..j).map(|i| i.checked_sub(1)).collect(), vec![Vec3::Y; j], 0.01)
                .unwrap(),
        )
    }

    #[test]
    fn motion_round_trip_and_shape_checks() {
        let s = skeleton(4);
        let positions: Vec<Vec3> = (0..20).map(|i| Vec3::new(i as f32, -(i as f32), 0.5)).collect();
        let m = Motion::from_positions(s.clone(), 30.0, positions.clone());
        let bytes = motion_to_npy(&m);
        let a = read_npy(&bytes, "m.npy").unwrap();
        assert_eq!(a.shape, vec![5, 4, 3]);
        let back = motion_from_npy(&bytes, "m.npy", s.clone(), 30.0).unwrap();
        assert_eq!(back.positions(), &positions[..]);
        assert_eq!(back.fps, 30.0);

        let e = motion_from_npy(&bytes, "m.npy", skeleton(22), 30.0).unwrap_err();
        assert_eq!(e.file, "m.npy");
        assert!(e.message.contains("(5, 4, 3)") && e.message.contains("(frames, 22, 3)"), "{e}");
        let flat = write_npy(&[60], &[0.0; 60]);
        let e = motion_from_npy(&flat, "flat.npy", s.clone(), 30.0).unwrap_err();
        assert!(e.message.contains("(60,)"), "{e}");
        let e = motion_from_npy(&write_npy(&[5, 4, 2], &[0.0; 40]), "m.npy", s.clone(), 30.0).unwrap_err();
        assert!(e.message.contains("(5, 4, 2)"), "{e}");
        assert!(motion_from_npy(&bytes, "m.npy", s.clone(), 0.0).is_err());
        let mut with_nan = vec![0.0f32; 12];
        with_nan[7] = f32::NAN;
        let e = motion_from_npy(&write_npy(&[1, 4, 3], &with_nan), "n.npy", s, 30.0).unwrap_err();
        assert!(e.message.contains("not finite") && e.message.contains("joint 2"), "{e}");
        assert!(motion_from_npy(&[], "e.npy", skeleton(2), 30.0).unwrap_err().message.contains("empty"));
    }
}
