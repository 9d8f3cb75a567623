//! A bounds-checked reader over the bytes of a mesh file: lines (ASCII parts), raw byte runs
//! (binary parts) and section skipping. Every read returns `None`/an error at the end of the
//! data instead of panicking; line numbers are computed only when an error needs one.
use flem_core::{FlemError, Result};

pub(crate) struct Cursor<'a> {
    pub src: &'a str,
    pub b: &'a [u8],
    pub pos: usize,
    /// Start of the last line or byte run read (errors point at its line).
    pub mark: usize,
}

impl<'a> Cursor<'a> {
    pub fn new(src: &'a str, b: &'a [u8]) -> Self {
        Cursor { src, b, pos: 0, mark: 0 }
    }

    /// 1-based line number of the last line read.
    pub fn line_no(&self) -> usize {
        1 + self.b[..self.mark.min(self.b.len())].iter().filter(|&&c| c == b'\n').count()
    }

    /// An error at the current line.
    pub fn err(&self, msg: impl std::fmt::Display) -> FlemError {
        FlemError::mesh(self.src, format!("line {}: {msg}", self.line_no()))
    }

    pub fn at_end(&self) -> bool {
        self.pos >= self.b.len()
    }

    /// Skips spaces, tabs, CR and LF.
    pub fn skip_ws(&mut self) {
        while self.pos < self.b.len() && self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    /// The next line without its line end, or `None` at the end of the data.
    pub fn line(&mut self) -> Option<&'a [u8]> {
        if self.at_end() {
            return None;
        }
        self.mark = self.pos;
        let rest = &self.b[self.pos..];
        let n = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
        self.pos += (n + 1).min(rest.len());
        let mut l = &rest[..n];
        while let [head @ .., b'\r'] = l {
            l = head;
        }
        Some(l)
    }

    /// The next line as trimmed text; an error naming `what` at the end of the data.
    pub fn text_line(&mut self, what: &str) -> Result<&'a str> {
        let line_start = self.pos;
        match self.line() {
            None => Err(self.err(format!("the file ends where {what} was expected"))),
            Some(l) => match std::str::from_utf8(l) {
                Ok(s) => Ok(s.trim()),
                Err(_) => {
                    self.pos = line_start;
                    Err(self.err(format!("{what}: not text")))
                }
            },
        }
    }

    /// `n` raw bytes.
    pub fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        self.mark = self.pos;
        match self.pos.checked_add(n) {
            Some(end) if end <= self.b.len() => {
                let s = &self.b[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            _ => Err(self.err(format!("the file ends inside {what}"))),
        }
    }

    /// Moves past the line `$End<name>` (searching byte-wise, so binary payloads are skipped).
    pub fn skip_section(&mut self, name: &str) -> Result<()> {
        let tag = format!("$End{name}");
        let rest = &self.b[self.pos.min(self.b.len())..];
        match rest.windows(tag.len()).position(|w| w == tag.as_bytes()) {
            Some(i) => {
                self.pos += i;
                self.line();
                Ok(())
            }
            None => Err(self.err(format!("section ${name} has no {tag}"))),
        }
    }

    /// Expects the line `$End<name>` (after optional blank space).
    pub fn expect_end(&mut self, name: &str) -> Result<()> {
        self.skip_ws();
        let l = self.text_line(&format!("$End{name}"))?;
        if l != format!("$End{name}") {
            return Err(self.err(format!("expected $End{name}, found \"{}\"", shorten(l))));
        }
        Ok(())
    }
}

/// At most 40 characters of `s`, for messages.
pub(crate) fn shorten(s: &str) -> String {
    let mut t: String = s.chars().take(40).collect();
    if s.chars().count() > 40 {
        t.push_str("...");
    }
    t
}

/// Parses one whitespace-separated token as `T`, naming `what` on failure.
pub(crate) fn parse_tok<T: std::str::FromStr>(c: &Cursor, tok: Option<&str>, what: &str) -> Result<T> {
    match tok {
        None => Err(c.err(format!("{what} is missing"))),
        Some(t) => t.parse().map_err(|_| c.err(format!("{what} \"{}\" is not a valid number", shorten(t)))),
    }
}
