//! Free text (file paths, robot names, options) written into another format's comments, headers
//! and markup: made one line of printable characters first, so that no path or name can end a
//! comment early and inject lines a parser would read (a YAML key, a `# frame: base` line), nor
//! put a control character where a TOML or XML reader refuses it.

use std::borrow::Cow;

/// `text` as one line of printable characters: every control character (`\n`, `\r`, tab, ...)
/// and every character a parser may take for a line break (NEL U+0085, LINE SEPARATOR U+2028,
/// PARAGRAPH SEPARATOR U+2029) written as its hexadecimal escape (a line feed as `\u{000a}`); the
/// rest unchanged.
///
/// ```
/// use host_tools::io::text::one_line;
/// assert_eq!(one_line("robots/ur10.toml"), "robots/ur10.toml");
/// assert_eq!(one_line("a\nkey: 1"), "a\\u{000a}key: 1");
/// assert_eq!(one_line("a\u{2028}b"), "a\\u{2028}b");
/// ```
pub fn one_line(text: &str) -> Cow<'_, str> {
    let unsafe_char = |c: char| c.is_control() || matches!(c, '\u{2028}' | '\u{2029}');
    if !text.chars().any(unsafe_char) {
        return Cow::Borrowed(text);
    }
    Cow::Owned(
        text.chars()
            .map(|c| {
                if unsafe_char(c) {
                    format!("\\u{{{:04x}}}", u32::from(c))
                } else {
                    c.to_string()
                }
            })
            .collect(),
    )
}

/// `text` for an XML attribute value or element text: [`one_line`], then `&`, `<`, `>`, `"`
/// and `'` as entities. The value reads back as the one-line text.
pub(crate) fn xml_attribute(text: &str) -> String {
    one_line(text)
        .replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}

/// `text` inside an XML comment: [`xml_attribute`]'s escapes, and a space between two hyphens
/// (a comment may not hold `--`) and after a final one (nor end in `-` before `-->`).
pub(crate) fn xml_comment(text: &str) -> String {
    let escaped = xml_attribute(text);
    let mut out = String::with_capacity(escaped.len());
    for c in escaped.chars() {
        if c == '-' && out.ends_with('-') {
            out.push(' ');
        }
        out.push(c);
    }
    if out.ends_with('-') {
        out.push(' ');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comments_hold_no_double_hyphen_and_attributes_keep_the_name() {
        assert_eq!(xml_comment("a---b-"), "a- - -b- ");
        assert!(!xml_comment("----").contains("--"));
        assert_eq!(xml_attribute("a---b"), "a---b");
        assert_eq!(
            xml_attribute("<a & \"b\">"),
            "&lt;a &amp; &quot;b&quot;&gt;"
        );
        assert_eq!(one_line("tab\there"), "tab\\u{0009}here");
        assert_eq!(one_line("nel\u{85}x"), "nel\\u{0085}x");
    }
}
