//! A writer of little-endian `float64` C-order arrays ([`npy_f64_bytes`], [`write_npy_f64`], format 1.0) and
//! a reader of NumPy `.npy` arrays of little-endian `float32` or `float64` in C order (format versions 1, 2
//! and 3: <https://numpy.org/doc/stable/reference/generated/numpy.lib.format.html>). Small and strict: any
//! other dtype, Fortran order or a truncated file is an error naming the file.

use std::path::{Path, PathBuf};

use thiserror::Error;

/// An error reading a `.npy` file.
#[derive(Clone, Debug, Error, PartialEq)]
#[error("{}: {problem}", path.display())]
pub struct NpyError {
    /// The file read.
    pub path: PathBuf,
    /// What is wrong.
    pub problem: String,
}

/// A C-order array read from `.npy`, widened to `f64`.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    /// The shape.
    pub shape: Vec<usize>,
    /// The values in C order (last index fastest).
    pub data: Vec<f64>,
}

/// Reads a `.npy` file.
pub fn read_npy(path: &Path) -> Result<NpyArray, NpyError> {
    let bytes = std::fs::read(path).map_err(|e| NpyError {
        path: path.to_path_buf(),
        problem: format!("cannot read the file ({e})"),
    })?;
    parse_npy(&bytes).map_err(|problem| NpyError {
        path: path.to_path_buf(),
        problem,
    })
}

/// Parses the bytes of a `.npy` file.
pub fn parse_npy(bytes: &[u8]) -> Result<NpyArray, String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a NumPy .npy file (the magic string \\x93NUMPY is missing)".into());
    }
    let major = bytes[6];
    let (header_len, header_start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err("truncated .npy header".into());
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => {
            return Err(format!(
                ".npy format version {v} is not supported (1, 2 or 3 are)"
            ));
        }
    };
    let header_end = header_start + header_len;
    if bytes.len() < header_end {
        return Err("truncated .npy header".into());
    }
    let header = std::str::from_utf8(&bytes[header_start..header_end])
        .map_err(|_| "the .npy header is not text".to_string())?;
    let descr = dict_value(header, "descr").ok_or("the .npy header has no 'descr'")?;
    let descr = descr.trim().trim_matches(|c| c == '\'' || c == '"');
    let width = match descr {
        "<f4" => 4,
        "<f8" => 8,
        other => {
            return Err(format!(
                "dtype '{other}' is not supported; store little-endian float32 ('<f4') or float64 ('<f8')"
            ));
        }
    };
    let fortran =
        dict_value(header, "fortran_order").ok_or("the .npy header has no 'fortran_order'")?;
    if fortran.trim() != "False" {
        return Err("Fortran-ordered arrays are not supported; save in C order".into());
    }
    let shape_text = dict_value(header, "shape").ok_or("the .npy header has no 'shape'")?;
    let inner = shape_text
        .trim()
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .ok_or_else(|| format!("cannot read the shape {shape_text}"))?;
    let shape = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<usize>()
                .map_err(|_| format!("cannot read the shape {shape_text}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let count = shape
        .iter()
        .try_fold(1usize, |a, &b| a.checked_mul(b))
        .ok_or("the shape overflows")?;
    let body = &bytes[header_end..];
    if body.len() != count * width {
        return Err(format!(
            "the data holds {} bytes but the shape {shape:?} of '{descr}' needs {}",
            body.len(),
            count * width
        ));
    }
    let data = if width == 4 {
        body.chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64)
            .collect()
    } else {
        body.chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
            .collect()
    };
    Ok(NpyArray { shape, data })
}

/// The bytes of a `.npy` file (format 1.0, dtype `<f8`, C order) holding `data` with `shape`. The header is
/// padded with spaces to a multiple of 64 bytes and ends in a newline, as NumPy writes it.
pub fn npy_f64_bytes(shape: &[usize], data: &[f64]) -> Vec<u8> {
    debug_assert_eq!(shape.iter().product::<usize>(), data.len());
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_text = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {shape_text}, }}");
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 8 * data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Writes [`npy_f64_bytes`] to `path`.
pub fn write_npy_f64(path: &Path, shape: &[usize], data: &[f64]) -> std::io::Result<()> {
    std::fs::write(path, npy_f64_bytes(shape, data))
}

/// The text of the value of `key` in the header's Python dict literal (up to the next top-level comma).
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pattern_single = format!("'{key}':");
    let pattern_double = format!("\"{key}\":");
    let start = header
        .find(&pattern_single)
        .map(|i| i + pattern_single.len())
        .or_else(|| {
            header
                .find(&pattern_double)
                .map(|i| i + pattern_double.len())
        })?;
    let rest = &header[start..];
    let mut depth = 0i32;
    for (i, c) in rest.char_indices() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ',' | '}' if depth == 0 => return Some(&rest[..i]),
            _ => {}
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_arrays_read_back_with_an_aligned_header() {
        for shape in [vec![5usize], vec![3, 4], vec![2, 0]] {
            let n: usize = shape.iter().product();
            let data: Vec<f64> = (0..n).map(|i| i as f64 * -1.25 + 1e-300).collect();
            let bytes = npy_f64_bytes(&shape, &data);
            let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
            assert_eq!((10 + header_len) % 64, 0, "{shape:?}");
            assert_eq!(bytes[9 + header_len], b'\n');
            let back = parse_npy(&bytes).unwrap();
            assert_eq!(back.shape, shape);
            assert_eq!(back.data, data);
        }
    }

    fn npy_bytes(version: u8, descr: &str, shape: &str, data: &[u8]) -> Vec<u8> {
        npy_bytes_order(version, descr, "False", shape, data)
    }

    fn npy_bytes_order(
        version: u8,
        descr: &str,
        fortran: &str,
        shape: &str,
        data: &[u8],
    ) -> Vec<u8> {
        let mut header =
            format!("{{'descr': '{descr}', 'fortran_order': {fortran}, 'shape': {shape}, }}");
        let prefix = if version == 1 { 10 } else { 12 };
        while (prefix + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut out = b"\x93NUMPY".to_vec();
        out.push(version);
        out.push(0);
        if version == 1 {
            out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        } else {
            out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        }
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(data);
        out
    }

    #[test]
    fn reads_v1_and_v2_float32_and_float64() {
        let values = [1.5f32, -2.0, 3.25, 0.0, 7.0, 8.5];
        let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        for version in [1, 2] {
            let a = parse_npy(&npy_bytes(version, "<f4", "(3, 2)", &data)).unwrap();
            assert_eq!(a.shape, vec![3, 2]);
            assert_eq!(a.data, values.iter().map(|&v| v as f64).collect::<Vec<_>>());
        }
        let data: Vec<u8> = [0.1f64, 0.2].iter().flat_map(|v| v.to_le_bytes()).collect();
        let a = parse_npy(&npy_bytes(1, "<f8", "(2,)", &data)).unwrap();
        assert_eq!(a.shape, vec![2]);
        assert_eq!(a.data, vec![0.1, 0.2]);
    }

    #[test]
    fn rejects_other_dtypes_orders_and_truncation() {
        let data = [0u8; 8];
        assert!(
            parse_npy(&npy_bytes(1, ">f4", "(2,)", &data))
                .unwrap_err()
                .contains("not supported")
        );
        assert!(
            parse_npy(&npy_bytes(1, "<f4", "(3,)", &data))
                .unwrap_err()
                .contains("needs 12")
        );
        let fortran = npy_bytes_order(1, "<f4", "True", "(2,)", &data);
        assert!(parse_npy(&fortran).unwrap_err().contains("Fortran"));
        assert!(
            parse_npy(b"not numpy at all")
                .unwrap_err()
                .contains("magic")
        );
    }
}
