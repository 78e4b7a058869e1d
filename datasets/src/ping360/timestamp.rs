//! Record time stamps of Ping Viewer logs: `hh:mm:ss.zzz`, the time since the
//! log began. Some files write the digits in another script (Extended
//! Arabic-Indic `۰۰:۰۰:۰۰.۳۹۴` in the committed logs), so every Unicode
//! decimal digit (general category Nd) is mapped to its value.

/// First code point (the digit zero) of every run of ten Unicode decimal
/// digits, Unicode 14; each run holds the values 0-9 in order.
const DIGIT_ZEROS: [u32; 66] = [
    0x30, 0x660, 0x6F0, 0x7C0, 0x966, 0x9E6, 0xA66, 0xAE6, 0xB66, 0xBE6, 0xC66, 0xCE6, 0xD66,
    0xDE6, 0xE50, 0xED0, 0xF20, 0x1040, 0x1090, 0x17E0, 0x1810, 0x1946, 0x19D0, 0x1A80, 0x1A90,
    0x1B50, 0x1BB0, 0x1C40, 0x1C50, 0xA620, 0xA8D0, 0xA900, 0xA9D0, 0xA9F0, 0xAA50, 0xABF0, 0xFF10,
    0x104A0, 0x10D30, 0x11066, 0x110F0, 0x11136, 0x111D0, 0x112F0, 0x11450, 0x114D0, 0x11650,
    0x116C0, 0x11730, 0x118E0, 0x11950, 0x11C50, 0x11D50, 0x11DA0, 0x16A60, 0x16AC0, 0x16B50,
    0x1D7CE, 0x1D7D8, 0x1D7E2, 0x1D7EC, 0x1D7F6, 0x1E140, 0x1E2F0, 0x1E950, 0x1FBF0,
];

/// The value of a Unicode decimal digit, `None` for any other character.
pub fn decimal_digit(c: char) -> Option<u32> {
    let code = u32::from(c);
    let k = DIGIT_ZEROS.partition_point(|&zero| zero <= code);
    let zero = *DIGIT_ZEROS.get(k.checked_sub(1)?)?;
    (code - zero < 10).then_some(code - zero)
}

/// Seconds of an `h+:mm:ss(.z+)?` stamp; `Err` says what is wrong.
pub fn parse_elapsed_s(text: &str) -> Result<f64, String> {
    let mut parts = [String::new(), String::new(), String::new(), String::new()];
    let mut part = 0;
    for c in text.chars() {
        match c {
            ':' if part < 2 => part += 1,
            '.' if part == 2 => part = 3,
            _ => match decimal_digit(c) {
                Some(d) => parts[part].push(char::from_digit(d, 10).unwrap_or('0')),
                None => return Err(format!("`{text}` is not hh:mm:ss.zzz")),
            },
        }
    }
    let [h, m, s, frac] = &parts;
    if part < 2 || h.is_empty() || m.len() != 2 || s.len() != 2 || (part == 3 && frac.is_empty()) {
        return Err(format!("`{text}` is not hh:mm:ss.zzz"));
    }
    let number = |t: &str| {
        t.parse::<f64>()
            .map_err(|_| format!("`{text}` is not hh:mm:ss.zzz"))
    };
    let (minutes, seconds) = (number(m)?, number(s)?);
    if minutes >= 60.0 || seconds >= 60.0 {
        return Err(format!("`{text}` has minutes or seconds of 60 or more"));
    }
    let fraction = if frac.is_empty() {
        0.0
    } else {
        number(&format!("0.{frac}"))?
    };
    Ok(number(h)? * 3600.0 + minutes * 60.0 + seconds + fraction)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_and_extended_arabic_indic_digits() {
        assert_eq!(parse_elapsed_s("00:01:02.500"), Ok(62.5));
        assert_eq!(parse_elapsed_s("۰۰:۰۰:۰۰.۳۹۴"), Ok(0.394));
        // Devanagari and fullwidth digits.
        assert_eq!(parse_elapsed_s("०१:००:००.००१"), Ok(3600.001));
        assert_eq!(
            parse_elapsed_s("１２:３４:５６"),
            Ok(12.0 * 3600.0 + 34.0 * 60.0 + 56.0)
        );
    }

    #[test]
    fn malformed_stamps_are_rejected() {
        for bad in [
            "",
            "12:34",
            "00:61:00.000",
            "00:00:00.",
            "00:00:0x.000",
            "1:2:3",
        ] {
            assert!(parse_elapsed_s(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn digit_table_edges() {
        assert_eq!(decimal_digit('0'), Some(0));
        assert_eq!(decimal_digit('9'), Some(9));
        assert_eq!(decimal_digit(':'), None);
        assert_eq!(decimal_digit('\u{6F9}'), Some(9));
        assert_eq!(decimal_digit('\u{6FA}'), None);
        assert_eq!(decimal_digit('\u{1FBF9}'), Some(9));
        assert_eq!(decimal_digit('a'), None);
    }
}
