//! Text written into the XML and HTML files the project makes (OpenSCENARIO, SUMO networks and
//! additionals, SVG drawings, HTML reports): one escape for all of them.

/// `text` safe as XML or HTML element content and as a double- or single-quoted attribute value:
/// the five special characters as entities (`'` as `&#39;`, which HTML and XML both read), tab,
/// newline and carriage return as character references (an attribute keeps them instead of
/// normalising them to spaces), and every other control character, which XML 1.0 does not allow
/// even as a reference, as a space.
pub fn xml_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            '\t' => out.push_str("&#9;"),
            '\n' => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            c if c.is_control() => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn specials_whitespace_and_control_characters() {
        assert_eq!(xml_escape("a & b < c > d \"e\" 'f'"), "a &amp; b &lt; c &gt; d &quot;e&quot; &#39;f&#39;");
        assert_eq!(xml_escape("τ 3 s\tok\u{1}\n\r"), "τ 3 s&#9;ok &#10;&#13;");
        assert_eq!(xml_escape("&amp;"), "&amp;amp;");
    }

    proptest! {
        /// Whatever the text, the escaped form has no character that ends content or an attribute
        /// and no control character, and unescaping gives the text back (controls but tab,
        /// newline and return as spaces).
        #[test]
        fn escaped_text_is_inert_and_round_trips(text in any::<String>()) {
            let e = xml_escape(&text);
            prop_assert!(!e.chars().any(|c| matches!(c, '<' | '>' | '"' | '\'') || c.is_control()));
            let back = e
                .replace("&lt;", "<")
                .replace("&gt;", ">")
                .replace("&quot;", "\"")
                .replace("&#39;", "'")
                .replace("&#9;", "\t")
                .replace("&#10;", "\n")
                .replace("&#13;", "\r")
                .replace("&amp;", "&");
            let expected: String =
                text.chars().map(|c| if c.is_control() && !matches!(c, '\t' | '\n' | '\r') { ' ' } else { c }).collect();
            prop_assert_eq!(back, expected);
        }
    }
}
