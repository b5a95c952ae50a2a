//! Unit tests of `pnml`.

use super::*;

#[test]
fn text_keeps_quotes_and_attributes_write_whitespace_as_character_references() {
    let s = "a&<>\"'\t\n\r";
    assert_eq!(text(s), "a&amp;&lt;&gt;\"'\t\n&#13;");
    assert_eq!(attr(s), "a&amp;&lt;&gt;&quot;&apos;&#9;&#10;&#13;");
    assert!(matches!(attr("plain text"), Cow::Borrowed(_)));
}

#[test]
fn counts_accept_plain_numbers_and_pipe_token_lists() {
    assert!(matches!(parse_count("3"), Ok(Some(3))));
    assert!(matches!(parse_count(" Default,2 "), Ok(Some(2))));
    assert!(matches!(parse_count("Default,1,Red,2"), Ok(Some(3))));
    assert!(matches!(parse_count(""), Ok(None)));
    assert!(matches!(parse_count("-1"), Err(CountError::Negative)));
    assert!(matches!(parse_count("x"), Err(CountError::NotNumber)));
    assert!(matches!(parse_count("1.5"), Err(CountError::NotNumber)));
    assert!(matches!(
        parse_count("99999999999"),
        Err(CountError::TooLarge)
    ));
    assert!(matches!(parse_count("Default"), Err(CountError::NotNumber)));
    assert!(matches!(
        parse_count("Default,1,Red"),
        Err(CountError::BadList)
    ));
}

#[test]
fn escaping_covers_markup_and_whitespace_that_parsers_normalise() {
    assert_eq!(text("a<b>&c\r"), "a&lt;b&gt;&amp;c&#13;");
    assert_eq!(attr("\"x'\t\n"), "&quot;x&apos;&#9;&#10;");
    assert!(matches!(text("plain"), Cow::Borrowed(_)));
}
