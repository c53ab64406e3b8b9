//! Byte offsets (the compiler's spans) ↔ LSP positions (line, UTF-16 code unit: the
//! protocol's default `positionEncoding`).

use lsp_types::{Position, Range};

/// Where each line of a text starts, to convert positions both ways.
#[derive(Clone, Debug)]
pub struct LineIndex {
    starts: Vec<usize>,
    len: usize,
}

impl LineIndex {
    /// The index of `text`.
    pub fn new(text: &str) -> Self {
        let mut starts = vec![0];
        starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        LineIndex {
            starts,
            len: text.len(),
        }
    }

    /// The position of byte `offset` (clamped to the text, moved back to a character
    /// boundary).
    pub fn position(&self, text: &str, offset: usize) -> Position {
        let mut offset = offset.min(self.len);
        while !text.is_char_boundary(offset) {
            offset -= 1;
        }
        let line = self.starts.partition_point(|&s| s <= offset) - 1;
        let start = self.starts[line];
        let character: usize = text[start..offset].chars().map(char::len_utf16).sum();
        Position {
            line: line as u32,
            character: character as u32,
        }
    }

    /// The range of a byte span.
    pub fn range(&self, text: &str, span: &std::ops::Range<usize>) -> Range {
        Range {
            start: self.position(text, span.start),
            end: self.position(text, span.end.max(span.start)),
        }
    }

    /// The byte offset of a position: a line past the end is the end of the text, a
    /// character past the end of its line the line's end.
    pub fn offset(&self, text: &str, pos: Position) -> usize {
        let Some(&start) = self.starts.get(pos.line as usize) else {
            return self.len;
        };
        let end = self
            .starts
            .get(pos.line as usize + 1)
            .map_or(self.len, |&e| e.saturating_sub(1));
        let mut units = 0usize;
        for (i, c) in text[start..end].char_indices() {
            if units >= pos.character as usize {
                return start + i;
            }
            units += c.len_utf16();
        }
        end
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_with_wide_characters() {
        let text = "ab\n// θ₁ → 𝛉\nx = 1";
        let li = LineIndex::new(text);
        for (i, _) in text.char_indices() {
            let p = li.position(text, i);
            assert_eq!(li.offset(text, p), i, "offset {i} at {p:?}");
        }
        assert_eq!(li.position(text, text.len()), Position::new(2, 5));
        assert_eq!(li.offset(text, Position::new(9, 0)), text.len());
        assert_eq!(li.offset(text, Position::new(0, 99)), 2);
        // 𝛉 is two UTF-16 units.
        let at = text.find('𝛉').unwrap();
        assert_eq!(li.position(text, at + '𝛉'.len_utf8()).character, 10);
    }
}
