//! The small pieces of HTML every page of the reports is made of: text escaped, numbers with
//! their decimals or "-", lists.

/// Text escaped for HTML.
pub(crate) fn esc(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('\u{22}', "&quot;")
}

/// A number of the report with `digits` decimals, or "-" when it is not a finite number (which
/// the JSON report writes as `null`).
pub(crate) fn num(value: f64, digits: usize) -> String {
    if value.is_finite() {
        format!("{value:.digits$}")
    } else {
        "-".to_string()
    }
}

/// An optional number of the report with `digits` decimals, or "-" when absent.
pub(crate) fn opt(value: Option<f64>, digits: usize) -> String {
    value.map_or_else(|| "-".to_string(), |v| num(v, digits))
}

/// Texts as a list: "none" when empty, else joined by commas (escaped).
pub(crate) fn list<T: AsRef<str>>(items: &[T]) -> String {
    if items.is_empty() {
        return "none".to_string();
    }
    (items.iter().map(|t| esc(t.as_ref())))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Text as a CSS string's content (inside `"..."` of a style sheet, which HTML does not decode):
/// backslashes and quotes escaped, `<` as `\3C ` so that no `</style>` can end the sheet, line
/// breaks as spaces.
pub(crate) fn css_string(text: &str) -> String {
    text.replace('\\', "\\\\")
        .replace('\u{22}', "\\\u{22}")
        .replace('<', "\\3C ")
        .replace(['\n', '\r'], " ")
}
