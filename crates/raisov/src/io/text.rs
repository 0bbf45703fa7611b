//! Small line- and token-oriented helpers shared by the ASCII readers. Every error they make
//! names the file and the 1-based line.

use std::path::Path;
use std::str::FromStr;

use crate::{Error, Result};

/// A format error at a known line.
pub(crate) fn format_err(path: &Path, line: usize, msg: impl Into<String>) -> Error {
    Error::MeshFormat {
        path: path.to_path_buf(),
        line: Some(line),
        msg: msg.into(),
    }
}

/// A format error without a line (binary files, whole-file problems).
pub(crate) fn format_err_noline(path: &Path, msg: impl Into<String>) -> Error {
    Error::MeshFormat {
        path: path.to_path_buf(),
        line: None,
        msg: msg.into(),
    }
}

/// Show a token in a message, shortened if it is long.
pub(crate) fn show(tok: &str) -> String {
    if tok.chars().count() > 40 {
        let s: String = tok.chars().take(40).collect();
        format!("`{s}...`")
    } else {
        format!("`{tok}`")
    }
}

/// Parse `tok` as a `T`, or explain what was expected.
pub(crate) fn parse_tok<T: FromStr>(path: &Path, line: usize, tok: &str, what: &str) -> Result<T> {
    tok.parse::<T>()
        .map_err(|_| format_err(path, line, format!("expected {what}, found {}", show(tok))))
}

/// Parse a finite float.
pub(crate) fn parse_f64(path: &Path, line: usize, tok: &str, what: &str) -> Result<f64> {
    let v: f64 = parse_tok(path, line, tok, what)?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format_err(
            path,
            line,
            format!("expected a finite number for {what}, found {}", show(tok)),
        ))
    }
}

/// Lines of a text file, skipping blank lines (and comments when a comment character is
/// given), remembering 1-based line numbers.
pub(crate) struct LineReader<'a> {
    pub path: &'a Path,
    lines: Vec<&'a str>,
    idx: usize,
    /// Line number of `lines[0]` minus one (for sections cut out of a larger file).
    offset: usize,
    comment: Option<char>,
}

impl<'a> LineReader<'a> {
    pub fn new(path: &'a Path, text: &'a str, comment: Option<char>) -> Self {
        LineReader {
            path,
            lines: text.lines().collect(),
            idx: 0,
            offset: 0,
            comment,
        }
    }

    /// A reader whose first line is line `first_line` (1-based) of the file.
    pub fn with_first_line(mut self, first_line: usize) -> Self {
        self.offset = first_line.saturating_sub(1);
        self
    }

    /// Line number just past the end, used for "unexpected end of file".
    pub fn eof_line(&self) -> usize {
        self.offset + self.lines.len() + 1
    }

    fn strip(&self, l: &'a str) -> &'a str {
        let l = match self.comment {
            Some(c) => l.split(c).next().unwrap_or(""),
            None => l,
        };
        l.trim()
    }

    /// Next non-blank line, or `None` at end of file.
    pub fn next_opt(&mut self) -> Option<(usize, &'a str)> {
        while self.idx < self.lines.len() {
            let l = self.strip(self.lines[self.idx]);
            self.idx += 1;
            if !l.is_empty() {
                return Some((self.offset + self.idx, l));
            }
        }
        None
    }

    /// Next non-blank line, or an "unexpected end of file, expected `what`" error.
    pub fn next(&mut self, what: &str) -> Result<(usize, &'a str)> {
        self.next_opt().ok_or_else(|| {
            format_err(
                self.path,
                self.eof_line(),
                format!("unexpected end of file, expected {what}"),
            )
        })
    }
}

/// Whitespace-separated tokens of a text, each with its 1-based line.
pub(crate) struct Tokens<'a> {
    pub path: &'a Path,
    lines: Vec<&'a str>,
    line_idx: usize,
    cur: std::str::SplitWhitespace<'a>,
    /// Line of the last token returned (1-based).
    pub line: usize,
}

impl<'a> Tokens<'a> {
    /// Tokens of `text`, starting at 0-based line `start_line`.
    pub fn new(path: &'a Path, text: &'a str, start_line: usize) -> Self {
        let lines: Vec<&str> = text.lines().collect();
        Tokens {
            path,
            line_idx: start_line,
            cur: "".split_whitespace(),
            line: start_line,
            lines,
        }
    }

    pub fn next_opt(&mut self) -> Option<&'a str> {
        loop {
            if let Some(t) = self.cur.next() {
                return Some(t);
            }
            if self.line_idx >= self.lines.len() {
                return None;
            }
            self.cur = self.lines[self.line_idx].split_whitespace();
            self.line_idx += 1;
            self.line = self.line_idx;
        }
    }

    pub fn next(&mut self, what: &str) -> Result<&'a str> {
        match self.next_opt() {
            Some(t) => Ok(t),
            None => Err(format_err(
                self.path,
                self.lines.len() + 1,
                format!("unexpected end of file, expected {what}"),
            )),
        }
    }

    pub fn parse<T: FromStr>(&mut self, what: &str) -> Result<T> {
        let t = self.next(what)?;
        parse_tok(self.path, self.line, t, what)
    }

    pub fn f64(&mut self, what: &str) -> Result<f64> {
        let t = self.next(what)?;
        parse_f64(self.path, self.line, t, what)
    }

    pub fn err(&self, msg: impl Into<String>) -> Error {
        format_err(self.path, self.line, msg)
    }

    /// Skip the rest of the current line and the lines after it up to and including the
    /// next blank one (a legacy VTK `METADATA` block).
    pub fn skip_to_blank_line(&mut self) {
        self.cur = "".split_whitespace();
        while self.line_idx < self.lines.len() {
            let l = self.lines[self.line_idx];
            self.line_idx += 1;
            self.line = self.line_idx;
            if l.trim().is_empty() {
                break;
            }
        }
    }
}
