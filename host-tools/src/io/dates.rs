//! Calendar dates as a certificate states them (`YYYY-MM-DD`), checked: a measurement date, an
//! instrument's calibration due date.

/// The date `text` (`YYYY-MM-DD`), checked, as `(year, month, day)` (ordered as dates are).
/// Refused: anything else, or a day the month does not have.
pub fn date(text: &str) -> Result<(u32, u32, u32), String> {
    let parts: Vec<&str> = text.split('-').collect();
    let number = |s: &str, digits: usize| {
        (s.len() == digits && s.bytes().all(|b| b.is_ascii_digit()))
            .then(|| s.parse::<u32>().ok())
            .flatten()
    };
    let parsed = match parts.as_slice() {
        [y, m, d] => number(y, 4).zip(number(m, 2)).zip(number(d, 2)),
        _ => None,
    };
    let Some(((year, month), day)) = parsed else {
        return Err("not a date YYYY-MM-DD".to_string());
    };
    // humantime checks the day against the month (leap years included).
    humantime::parse_rfc3339(&format!("{text}T00:00:00Z"))
        .map_err(|_| format!("{text} is not a day of the calendar"))?;
    Ok((year, month, day))
}

#[cfg(test)]
mod tests {
    use super::date;

    #[test]
    fn dates_are_checked_against_the_calendar() {
        assert_eq!(date("2026-11-29"), Ok((2026, 11, 29)));
        assert!(date("2028-02-29").is_ok());
        assert!(date("2026-02-29").is_err());
        assert!(date("2026-13-01").is_err());
        assert!(date("29.11.2026").is_err());
        assert!(date("2026-1-01").is_err());
        assert!(date("2026-11-29") > date("2026-11-28"));
    }
}
