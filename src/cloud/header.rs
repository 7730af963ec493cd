//! What the PCD and PLY readers share: a file's bytes, read whole (an I/O error names the
//! file), and the lines of its text header.

use std::path::Path;

use super::error::CloudError;

pub(crate) fn read(path: &Path) -> Result<Vec<u8>, CloudError> {
    std::fs::read(path).map_err(|source| CloudError::Io {
        path: path.to_owned(),
        source,
    })
}

/// The next line of a PCD or PLY text header at `*pos` (trimmed), moving `*pos` past it;
/// `ends_before` says what the header lacks when it has no more lines.
pub(crate) fn header_line<'a>(
    bytes: &'a [u8],
    pos: &mut usize,
    ends_before: &str,
) -> Result<&'a str, String> {
    let end = bytes[*pos..]
        .iter()
        .position(|&b| b == b'\n')
        .ok_or_else(|| format!("header ends before {ends_before}"))?;
    let line = std::str::from_utf8(&bytes[*pos..*pos + end]).map_err(|_| "header is not text")?;
    *pos += end + 1;
    Ok(line.trim())
}
