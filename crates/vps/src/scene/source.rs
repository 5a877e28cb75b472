//! The scene text as the parser sees it: byte spans turned into lines and columns, and the
//! allowed key that a mistyped one most likely meant.

use std::path::{Path, PathBuf};

use super::error::{Location, SHOWN_CHARS};

/// The text being parsed, for turning byte spans into locations.
pub(super) struct Source<'a> {
    text: &'a str,
    file: Option<&'a Path>,
    /// Byte offset of the start of each line.
    line_starts: Vec<usize>,
}

impl<'a> Source<'a> {
    pub(super) fn new(text: &'a str, file: Option<&'a Path>) -> Self {
        let line_starts = std::iter::once(0)
            .chain(
                text.bytes()
                    .enumerate()
                    .filter(|&(_, b)| b == b'\n')
                    .map(|(i, _)| i + 1),
            )
            .collect();
        Source {
            text,
            file,
            line_starts,
        }
    }

    /// The line of a byte offset, from 1: a binary search, as every entry asks for its line.
    pub(super) fn line_of(&self, offset: usize) -> usize {
        self.line_starts.partition_point(|&s| s <= offset).max(1)
    }

    /// The location of a byte offset: line and column (in characters) from 1. The column
    /// costs the length of the line, so it is worked out only for errors.
    pub(super) fn at(&self, offset: usize) -> Location {
        let offset = offset.min(self.text.len());
        let line = self.line_of(offset);
        let bytes = &self.text.as_bytes()[self.line_starts[line - 1]..offset];
        // Characters, not bytes: count the bytes that start a UTF-8 sequence.
        let column = 1 + bytes.iter().filter(|&&b| (b & 0xC0) != 0x80).count();
        Location {
            file: self.file.map(Path::to_path_buf),
            line,
            column,
        }
    }

    pub(super) fn at_span(&self, span: Option<std::ops::Range<usize>>) -> Location {
        match span {
            Some(s) => self.at(s.start),
            None => self.nowhere(),
        }
    }

    pub(super) fn nowhere(&self) -> Location {
        Location {
            file: self.file.map(Path::to_path_buf),
            line: 0,
            column: 0,
        }
    }

    pub(super) fn file(&self) -> Option<PathBuf> {
        self.file.map(Path::to_path_buf)
    }
}

/// The allowed key closest to `key` (edit distance at most 2, or differing only in case,
/// `-` for `_` or a plural `s`), if any.
pub(super) fn closest(key: &str, allowed: &'static [&'static str]) -> Option<&'static str> {
    if key.len() > SHOWN_CHARS {
        return None;
    }
    let norm = |s: &str| s.to_ascii_lowercase().replace('-', "_");
    let k = norm(key);
    if let Some(a) = allowed.iter().find(|a| norm(a) == k || format!("{}s", norm(a)) == k) {
        return Some(a);
    }
    // A shortened key: `euler` for `euler_degrees`, `quat` for `quaternion`.
    if k.len() >= 3 {
        if let Some(a) = allowed.iter().find(|a| a.starts_with(k.as_str())) {
            return Some(a);
        }
    }
    allowed
        .iter()
        .map(|a| (edit_distance(&k, a), *a))
        .filter(|&(d, _)| d <= 2)
        .min_by_key(|&(d, _)| d)
        .map(|(_, a)| a)
}

/// Levenshtein distance, in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let next = (diag + (ca != cb) as usize).min(row[j] + 1).min(row[j + 1] + 1);
            diag = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}
