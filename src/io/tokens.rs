//! Whitespace tokenizer that remembers line numbers, shared by every text reader.

use super::LoadError;
use std::path::Path;

/// What one record of a file holds, for messages that say where a record went out of step.
pub struct RecordLayout {
    /// "a body record", "a constraint record", ...
    pub name: &'static str,
    /// Its fields in order, e.g. `["m1", "v1", "m2", "v2", "lower", "upper"]`.
    pub fields: &'static [&'static str],
}

/// A line that does not hold one whole record: where, how many fields, and what a record is.
struct LayoutBreak {
    line: usize,
    fields: usize,
    layout: &'static RecordLayout,
}

impl LayoutBreak {
    fn describe(&self) -> String {
        format!(
            "holds {} fields where {} has {}: {}",
            self.fields,
            self.layout.name,
            self.layout.fields.len(),
            self.layout.fields.join(" ")
        )
    }

    /// The break as a note to an error found on a later line.
    fn note(&self) -> String {
        format!("line {} {}", self.line, self.describe())
    }
}

pub struct Token<'a> {
    pub text: &'a str,
    pub line: usize,
}

/// Splits `text` into whitespace-separated tokens, dropping `#` comments (to end of line).
/// Tolerates CRLF and lone CR line endings ([`lines`]), tabs and blank lines.
pub struct Tokens<'a> {
    tokens: Vec<Token<'a>>,
    next: usize,
    file: &'a Path,
    last_line: usize,
    /// The first line of the current run of records that does not hold one whole record, named
    /// in every error on it or after it: how a record read out of step shows.
    layout_break: Option<LayoutBreak>,
    /// The line of the last count read by [`Tokens::count_records`] and its records' width
    /// (not [`Tokens::count`]'s, which may share its line with other numbers).
    count_line: Option<(usize, usize)>,
}

/// The lines of `text`, each ended by `\n`, `\r\n` or a lone `\r` (the line end of classic
/// Mac OS files): with `str::lines`, which ends lines at `\n` only, such a file was one line,
/// all of it comment after a `#` on its first, and every error named line 1. As `str::lines`,
/// no empty line after the last line end.
fn lines(text: &str) -> impl Iterator<Item = &str> {
    let mut rest = text;
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        let (line, after) = match rest.find(['\r', '\n']) {
            Some(at) if rest[at..].starts_with("\r\n") => (&rest[..at], at + 2),
            Some(at) => (&rest[..at], at + 1),
            None => (rest, rest.len()),
        };
        rest = &rest[after..];
        Some(line)
    })
}

/// A file's bytes as the readers' text. Bytes that are not UTF-8 (a Latin-1 or Windows-1252
/// accent, say) may stand in `#` comments, which no reader looks at (as the coursework's byte
/// stream readers take any); elsewhere, and for UTF-16 text (Windows Notepad's "Unicode",
/// PowerShell's `>`), whose NUL bytes made words of garbage, the error says to save the file
/// as UTF-8. NUL or DOS end-of-file (Ctrl-Z) bytes that pad the end are no part of the text.
pub fn decode_text(file: &Path, bytes: Vec<u8>) -> Result<String, LoadError> {
    let save_as = "save it as UTF-8";
    if looks_like_utf16(&bytes) {
        let message = format!("the file is UTF-16 text, which the readers do not take: {save_as}");
        return Err(LoadError::new(file, None, message));
    }
    let (mut text, lossy) = match String::from_utf8(bytes) {
        Ok(text) => (text, false),
        Err(e) => (String::from_utf8_lossy(e.as_bytes()).into_owned(), true),
    };
    let padded = text.trim_end_matches(['\0', '\u{1a}']).len();
    text.truncate(padded);
    if !lossy && !text.contains('\0') {
        return Ok(text);
    }
    for (index, line) in lines(&text).enumerate() {
        let content = line.find('#').map_or(line, |at| &line[..at]);
        let problem = if lossy && content.contains('\u{fffd}') {
            "bytes that are not UTF-8 text (a Latin-1 or Windows-1252 accent?)"
        } else if content.contains('\0') {
            "a NUL byte"
        } else {
            continue;
        };
        let message =
            format!("not a text file the readers take: {problem} outside a comment; {save_as}");
        return Err(LoadError::new(file, Some(index + 1), message));
    }
    Ok(text)
}

/// A UTF-16 byte-order mark, or (without one) a start of 64 bytes whose even or odd bytes are
/// mostly NUL and the others mostly printable ASCII, as ASCII text in UTF-16 is (a binary file
/// of small integers has the NULs, not the text).
fn looks_like_utf16(bytes: &[u8]) -> bool {
    if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
        return true;
    }
    let head = &bytes[..bytes.len().min(64)];
    let pairs = head.len() / 2;
    let count = |parity: usize, test: fn(&u8) -> bool| {
        let places = head.iter().skip(parity).step_by(2).take(pairs);
        places.filter(|b| test(b)).count()
    };
    let mostly = |n: usize| pairs >= 2 && n * 4 >= pairs * 3;
    let nul = |b: &u8| *b == 0;
    let ascii = |b: &u8| b.is_ascii_graphic() || b.is_ascii_whitespace();
    [(0, 1), (1, 0)]
        .into_iter()
        .any(|(zeros, text)| mostly(count(zeros, nul)) && mostly(count(text, ascii)))
}

impl<'a> Tokens<'a> {
    pub fn new(file: &'a Path, text: &'a str) -> Self {
        // A byte-order mark (some Windows editors write one) is not a word of the file.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut tokens = Vec::new();
        let mut last_line = 1;
        for (index, line) in lines(text).enumerate() {
            let content = match line.find('#') {
                Some(at) => &line[..at],
                None => line,
            };
            for word in content.split_whitespace() {
                tokens.push(Token {
                    text: word,
                    line: index + 1,
                });
            }
            last_line = index + 1;
        }
        Self {
            tokens,
            next: 0,
            file,
            last_line,
            layout_break: None,
            count_line: None,
        }
    }

    /// The words on `line`, for messages that say what a line holds.
    pub fn fields_on(&self, line: usize) -> impl Iterator<Item = &'a str> + '_ {
        let start = self.tokens.partition_point(|t| t.line < line);
        let on_line = self.tokens[start..]
            .iter()
            .take_while(move |t| t.line == line);
        on_line.map(|t| t.text)
    }

    /// Refuses words after the last of the `declared` records ("3 bodies"): a count smaller
    /// than its records. Where the last count's line holds a whole record's fields, the count
    /// line may be missing, the first record's first field read as the count: said so.
    pub fn expect_end(&self, declared: &str) -> Result<(), LoadError> {
        let Some(extra) = self.peek() else {
            return Ok(());
        };
        let message = format!("the file declares {declared} but has more records after them");
        match self.count_line {
            // Said instead of the layout's note, which would count the line's fields after the
            // count.
            Some((line, width)) if self.fields_on(line).count() == width => Err(LoadError::new(
                self.file,
                Some(extra.line),
                format!(
                    "{message} (line {line}, read as the count, holds {width} fields, as a record does: is the count line missing?)"
                ),
            )),
            _ => Err(self.error(extra.line, message)),
        }
    }

    /// An error at `line`; past a line that breaks the records' layout it names that line too.
    pub fn error(&self, line: usize, message: impl Into<String>) -> LoadError {
        let mut message = message.into();
        if let Some(at) = &self.layout_break
            && at.line <= line
        {
            message = format!("{message} ({})", at.note());
        }
        LoadError::new(self.file, Some(line), message)
    }

    /// Notes that `count` records of `layout` follow. The readers take any white space between
    /// fields, as the coursework's stream readers do, but every coursework file holds one record
    /// a line, so the first line that does not is where a missing or extra field shows.
    pub fn begin_records(&mut self, count: usize, layout: &'static RecordLayout) {
        let width = layout.fields.len();
        let mut end = self.tokens.len().min(self.next + count * width);
        // The window's last line counted whole: a field too many on it is a break too.
        while end > self.next
            && end < self.tokens.len()
            && self.tokens[end].line == self.tokens[end - 1].line
        {
            end += 1;
        }
        self.layout_break = self.tokens[self.next..end]
            .chunk_by(|a, b| a.line == b.line)
            .find(|line| line.len() != width)
            .map(|line| LayoutBreak {
                line: line[0].line,
                fields: line.len(),
                layout,
            });
    }

    /// The line that breaks the layout of the records read since [`Tokens::begin_records`], as
    /// an error message, for a file that loaded but may not hold what was meant.
    pub fn layout_warning(&self) -> Option<LoadError> {
        self.layout_break.as_ref().map(|at| {
            let message = format!(
                "the line {}; read as one stream of words, as the coursework's reader reads it, the records from here on may not be what was meant",
                at.describe()
            );
            LoadError::new(self.file, Some(at.line), message)
        })
    }

    /// Tokens not yet consumed: an upper bound on how many records can follow, used to refuse
    /// absurd counts before allocating for them.
    pub fn remaining(&self) -> usize {
        self.tokens.len() - self.next
    }

    pub fn peek(&self) -> Option<&Token<'a>> {
        self.tokens.get(self.next)
    }

    /// Line of the next token, or of the end of the file.
    pub fn line(&self) -> usize {
        self.peek().map_or(self.last_line, |t| t.line)
    }

    pub fn next(&mut self, what: &str) -> Result<&Token<'a>, LoadError> {
        match self.tokens.get(self.next) {
            Some(token) => {
                self.next += 1;
                Ok(token)
            }
            None => Err(LoadError::new(
                self.file,
                Some(self.last_line),
                format!("unexpected end of file: expected {what}"),
            )),
        }
    }

    /// A finite real number.
    pub fn real(&mut self, what: &str) -> Result<(f64, usize), LoadError> {
        let token = self.next(what)?;
        let (text, line) = (token.text, token.line);
        match text.parse::<f64>() {
            Ok(value) if value.is_finite() => Ok((value, line)),
            Ok(_) => Err(self.error(line, format!("{what} must be finite, found '{text}'"))),
            Err(_) => Err(self.error(line, format!("expected {what} (a number), found '{text}'"))),
        }
    }

    /// A non-negative integer (accepts "3" and "3.0", as hand-written files often do).
    pub fn index(&mut self, what: &str) -> Result<(usize, usize), LoadError> {
        let token = self.next(what)?;
        let (text, line) = (token.text, token.line);
        if let Ok(value) = text.parse::<usize>() {
            return Ok((value, line));
        }
        match text.parse::<f64>() {
            Ok(v) if v >= 0.0 && v.fract() == 0.0 && v < 1e15 => Ok((v as usize, line)),
            _ => Err(self.error(
                line,
                format!("expected {what} (a non-negative integer), found '{text}'"),
            )),
        }
    }

    /// A count of records that follow, each of at least `tokens_per_record` tokens, at most
    /// `limit`.
    pub fn count(
        &mut self,
        what: &str,
        tokens_per_record: usize,
        limit: usize,
    ) -> Result<usize, LoadError> {
        let (count, line) = self.index(what)?;
        self.layout_break = None;
        self.count_line = None;
        self.check_count(what, (count, line), tokens_per_record, limit)
    }

    /// A count of records of `layout` that follow one a line, at most `limit`; errors from here
    /// on name the first line that breaks the layout ([`Tokens::begin_records`]).
    pub fn count_records(
        &mut self,
        what: &str,
        layout: &'static RecordLayout,
        limit: usize,
    ) -> Result<usize, LoadError> {
        let (count, line) = self.index(what)?;
        self.count_line = Some((line, layout.fields.len()));
        self.begin_records(count.min(limit), layout);
        self.check_count(what, (count, line), layout.fields.len(), limit)
    }

    fn check_count(
        &self,
        what: &str,
        (count, line): (usize, usize),
        tokens_per_record: usize,
        limit: usize,
    ) -> Result<usize, LoadError> {
        if count > limit {
            return Err(self.error(
                line,
                format!("{what} is {count}, more than the limit of {limit}"),
            ));
        }
        let available = self.remaining() / tokens_per_record.max(1);
        if count > available {
            let holds = match available {
                0 => "none".to_string(),
                1 => "at most 1 such record".to_string(),
                n => format!("at most {n} such records"),
            };
            let mut message = format!("{what} says {count} but the file holds {holds}");
            if let Some(at) = &self.layout_break {
                message = format!("{message} ({})", at.note());
            }
            return Err(LoadError::new(self.file, Some(line), message));
        }
        Ok(count)
    }
}

#[cfg(test)]
mod tests {
    use super::lines;

    /// Lines end at LF, CRLF or a lone CR; a CR then a CRLF (a CRLF file converted twice) is two
    /// line ends, as Python's universal newlines read it; no empty line after the last end.
    #[test]
    fn lines_end_at_lf_crlf_or_a_lone_cr() {
        fn split(text: &str) -> Vec<&str> {
            lines(text).collect()
        }
        assert_eq!(split("a\r\nb\rc\nd"), ["a", "b", "c", "d"]);
        assert_eq!(split("a\r"), ["a"]);
        assert_eq!(split("a\r\r\nb"), ["a", "", "b"]);
        assert_eq!(split("\n\n"), ["", ""]);
        assert!(split("").is_empty());
        assert_eq!(split("a"), ["a"]);
    }
}
