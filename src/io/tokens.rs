//! Whitespace tokenizer that remembers line numbers, shared by every text reader.

use super::LoadError;
use std::path::Path;

pub struct Token<'a> {
    pub text: &'a str,
    pub line: usize,
}

/// Splits `text` into whitespace-separated tokens, dropping `#` comments (to end of line).
/// Tolerates CRLF line endings, tabs and blank lines.
pub struct Tokens<'a> {
    tokens: Vec<Token<'a>>,
    next: usize,
    file: &'a Path,
    last_line: usize,
}

impl<'a> Tokens<'a> {
    pub fn new(file: &'a Path, text: &'a str) -> Self {
        let mut tokens = Vec::new();
        let mut last_line = 1;
        for (index, line) in text.lines().enumerate() {
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
        }
    }

    pub fn error(&self, line: usize, message: impl Into<String>) -> LoadError {
        LoadError::new(self.file, Some(line), message)
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

    /// A count of records that follow, each of at least `tokens_per_record` tokens, at most `limit`.
    pub fn count(
        &mut self,
        what: &str,
        tokens_per_record: usize,
        limit: usize,
    ) -> Result<usize, LoadError> {
        let (count, line) = self.index(what)?;
        if count > limit {
            return Err(self.error(
                line,
                format!("{what} is {count}, more than the limit of {limit}"),
            ));
        }
        let available = self.remaining() / tokens_per_record.max(1);
        if count > available {
            return Err(self.error(
                line,
                format!("{what} says {count} but the file holds at most {available} such records"),
            ));
        }
        Ok(count)
    }
}
