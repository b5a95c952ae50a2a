//! The lexer: a text as a list of tokens, each its kind and its byte span (12 bytes, nothing
//! borrowed or allocated). The parser reads a name or a literal's value from the text when it
//! builds the node, so lexing allocates the token list and nothing else.
//!
//! Lexical choices, where IEC 61131-3 (3rd edition) or MATIEC leaves one:
//!
//! * **Comments do not nest.** `(* … *)`, `/* … */` and `// …` to the end of the line;
//!   `(* a (* b *) c *)` ends at the first `*)`, and `c *)` is then a syntax error. The 3rd
//!   edition lists nested comments as an optional feature (Table 5) and MATIEC has them only
//!   behind an option; with one rule, a stray `(*` inside a comment cannot swallow the rest of a
//!   file. Pragmas `{ … }` (CODESYS attributes) are skipped, and do not nest either.
//! * **Names** are MATIEC's: ASCII letters, digits and single underscores, not starting with a
//!   digit, with no `__` and no trailing `_` (IEC 61131-3 §6.1.2). Names and keywords are
//!   case-insensitive.
//! * **Numbers**: `_` only between two digits; bases `2#`, `8#` and `16#`; a REAL needs a `.`
//!   followed by digits (`1.0E5`): `2e5` and `1.` are refused, as IEC and MATIEC refuse them.
//! * **Strings** are single-quoted, on one line, with the `$` escapes of IEC (`$$ $' $" $L $N $P
//!   $R $T` and `$` with two hex digits); a double-quoted string is a WSTRING, refused by name.
//! * **Typed literals** (`INT#-5`, `WORD#16#FF`, `Color#Red`, `T#1s500ms`, `STRING#'a'`) are one
//!   token: the prefix, `#`, an optional sign and the value, with no spaces. Date and
//!   time-of-day literals (`D#`, `TOD#`, `DT#`, …) are refused by name.
//! * **Words IEC reserves but programs use as names** are not keywords here: the elementary type
//!   names, `DT`, `TOD`, `DATE`, `ON`, `WITH`, `TASK`, `STEP`, `ACTION`, `TRANSITION`. The parser
//!   gives them their meaning where one is expected (a type, a resource, a statement).

use crate::ast::{Pos, Rel};
use crate::error::Diagnostic;
use crate::parse::{DATES, MAX_TOKENS, WSTRING};

/// The kinds of token; the text of a name or literal is its span.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Tok {
    /// A name that is not a keyword.
    Ident,
    /// A keyword.
    Kw(Kw),
    /// `5`, `1_000`, `16#FF`.
    Int,
    /// `1.5`, `1.0E-3`.
    Real,
    /// `T#1s`, `LTIME#5ms`: the prefix included.
    Time,
    /// `'text'`: the quotes included.
    Str,
    /// `INT#-5`, `Color#Red`, `BOOL#TRUE`, `STRING#'a'`: prefix, `#` and value.
    Typed,
    /// `%IX0.0`.
    Address,
    /// `:=`.
    Assign,
    /// `=>`.
    Arrow,
    /// `:`.
    Colon,
    /// `;`.
    Semi,
    /// `,`.
    Comma,
    /// `.`.
    Dot,
    /// `..`.
    DotDot,
    /// `(`.
    LParen,
    /// `)`.
    RParen,
    /// `[`.
    LBracket,
    /// `]`.
    RBracket,
    /// `+`.
    Plus,
    /// `-`.
    Minus,
    /// `*`.
    Star,
    /// `**`.
    Power,
    /// `/`.
    Slash,
    /// `&`.
    Amp,
    /// A comparison: `=`, `<>`, `<`, `<=`, `>`, `>=`.
    Rel(Rel),
    /// `^`: only to be refused by name.
    Caret,
    /// The end of the text; always the last token.
    End,
    /// Where lexing stopped on an error ([`Lexed::error`]); followed only by `End`.
    Error,
}

/// A token: its kind and where it is.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Token {
    /// What it is.
    pub(crate) tok: Tok,
    /// Its first byte.
    pub(crate) pos: Pos,
    /// One past its last byte.
    pub(crate) end: Pos,
}

/// A lexed text: tokens up to the end of the text or up to the first lexical error.
pub(crate) struct Lexed {
    /// The tokens, ending in `End` (after an `Error` token when lexing failed).
    pub(crate) tokens: Vec<Token>,
    /// The lexical error the `Error` token stands for. The parser reports it when it reaches
    /// that token, so errors come in the order of the text.
    pub(crate) error: Option<Diagnostic>,
}

macro_rules! keywords {
    ($($kw:ident = $text:literal,)*) => {
        /// The reserved words the parser reads, or refuses by name.
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub(crate) enum Kw {
            $(#[doc = $text] $kw,)*
        }

        impl Kw {
            /// The keyword in upper case.
            pub(crate) const fn text(self) -> &'static str {
                match self {
                    $(Kw::$kw => $text,)*
                }
            }

            /// Every keyword.
            const ALL: &'static [Kw] = &[$(Kw::$kw,)*];
        }
    };
}

keywords! {
    And = "AND",
    Array = "ARRAY",
    At = "AT",
    By = "BY",
    Case = "CASE",
    Class = "CLASS",
    Configuration = "CONFIGURATION",
    Constant = "CONSTANT",
    Continue = "CONTINUE",
    Do = "DO",
    Else = "ELSE",
    Elsif = "ELSIF",
    EndAction = "END_ACTION",
    EndCase = "END_CASE",
    EndClass = "END_CLASS",
    EndConfiguration = "END_CONFIGURATION",
    EndFor = "END_FOR",
    EndFunction = "END_FUNCTION",
    EndFunctionBlock = "END_FUNCTION_BLOCK",
    EndIf = "END_IF",
    EndInterface = "END_INTERFACE",
    EndMethod = "END_METHOD",
    EndProgram = "END_PROGRAM",
    EndProperty = "END_PROPERTY",
    EndRepeat = "END_REPEAT",
    EndResource = "END_RESOURCE",
    EndStep = "END_STEP",
    EndStruct = "END_STRUCT",
    EndTransition = "END_TRANSITION",
    EndType = "END_TYPE",
    EndVar = "END_VAR",
    EndWhile = "END_WHILE",
    Exit = "EXIT",
    Extends = "EXTENDS",
    False = "FALSE",
    For = "FOR",
    Function = "FUNCTION",
    FunctionBlock = "FUNCTION_BLOCK",
    If = "IF",
    Implements = "IMPLEMENTS",
    InitialStep = "INITIAL_STEP",
    Interface = "INTERFACE",
    Jmp = "JMP",
    Method = "METHOD",
    Mod = "MOD",
    NonRetain = "NON_RETAIN",
    Not = "NOT",
    Of = "OF",
    Or = "OR",
    Persistent = "PERSISTENT",
    Program = "PROGRAM",
    Property = "PROPERTY",
    RefTo = "REF_TO",
    Repeat = "REPEAT",
    Resource = "RESOURCE",
    Retain = "RETAIN",
    Return = "RETURN",
    String = "STRING",
    Struct = "STRUCT",
    Then = "THEN",
    To = "TO",
    True = "TRUE",
    Type = "TYPE",
    Until = "UNTIL",
    Var = "VAR",
    VarAccess = "VAR_ACCESS",
    VarConfig = "VAR_CONFIG",
    VarExternal = "VAR_EXTERNAL",
    VarGlobal = "VAR_GLOBAL",
    VarInput = "VAR_INPUT",
    VarInOut = "VAR_IN_OUT",
    VarOutput = "VAR_OUTPUT",
    VarTemp = "VAR_TEMP",
    While = "WHILE",
    Wstring = "WSTRING",
    Xor = "XOR",
}

impl Kw {
    /// `END_…`: a keyword that closes something, so a body before it ends.
    pub(crate) fn is_end(self) -> bool {
        self.text().starts_with("END_")
    }
}

/// The longest keyword (`END_FUNCTION_BLOCK`) fits this buffer.
const KEYWORD_MAX: usize = 20;

/// `word` in upper case in `buf`, if it is short enough to be a keyword or a literal prefix.
fn upper<'b>(word: &[u8], buf: &'b mut [u8; KEYWORD_MAX]) -> Option<&'b [u8]> {
    let out = buf.get_mut(..word.len())?;
    for (o, b) in out.iter_mut().zip(word) {
        *o = b.to_ascii_uppercase();
    }
    Some(out)
}

/// Slots of the keyword table: a power of two, about four times the keywords, so that a name
/// that is not a keyword nearly always lands on an empty slot at once.
const SLOTS: usize = 512;

/// FNV-1a of an upper-case word, as a slot.
const fn slot_of(word: &[u8]) -> usize {
    let mut h: u32 = 0x811c_9dc5;
    let mut i = 0;
    while i < word.len() {
        h = (h ^ word[i] as u32).wrapping_mul(0x0100_0193);
        i += 1;
    }
    h as usize % SLOTS
}

/// The keywords by the hash of their text, with linear probing; built by the compiler. Every
/// name is looked up, and most are not keywords: one hash and (nearly always) one probe.
const KEYWORDS: [Option<Kw>; SLOTS] = {
    let mut table = [None; SLOTS];
    let mut k = 0;
    while k < Kw::ALL.len() {
        let kw = Kw::ALL[k];
        let mut slot = slot_of(kw.text().as_bytes());
        while table[slot].is_some() {
            slot = (slot + 1) % SLOTS;
        }
        table[slot] = Some(kw);
        k += 1;
    }
    table
};

/// The keyword `word` is, in any case.
fn keyword(word: &[u8]) -> Option<Kw> {
    let mut buf = [0; KEYWORD_MAX];
    let word = upper(word, &mut buf)?;
    let mut slot = slot_of(word);
    // Ends: the table has more slots than keywords, so an empty one is always reached.
    loop {
        match KEYWORDS.get(slot).copied().flatten() {
            None => return None,
            Some(kw) if kw.text().as_bytes() == word => return Some(kw),
            Some(_) => slot = (slot + 1) % SLOTS,
        }
    }
}

/// Lexes `text` (at most [`crate::parse::MAX_TEXT`] bytes, so every offset fits a [`Pos`]).
/// A text of more than [`MAX_TOKENS`] tokens is refused at once, before anything is parsed, so
/// that no tree grows to the cap; any other lexical error is left for the parser to report in
/// its place ([`Lexed::error`]).
pub(crate) fn lex(text: &str) -> Result<Lexed, Diagnostic> {
    let mut lexer = Lexer {
        text,
        b: text.as_bytes(),
        i: if text.starts_with('\u{feff}') { 3 } else { 0 },
    };
    // About one token per four bytes in real programs; a guess, grown if short.
    let mut tokens = Vec::with_capacity((text.len() / 3).min(MAX_TOKENS) + 2);
    let error = loop {
        if let Err(e) = lexer.skip_trivia() {
            break Some(e);
        }
        if lexer.i >= lexer.b.len() {
            break None;
        }
        if tokens.len() >= MAX_TOKENS {
            return Err(Diagnostic::new(
                lexer.i as Pos,
                format!(
                    "the text has more than {MAX_TOKENS} tokens, the limit; split it into several files"
                ),
            ));
        }
        let start = lexer.i;
        match lexer.token() {
            Ok(tok) => tokens.push(Token {
                tok,
                pos: start as Pos,
                end: lexer.i as Pos,
            }),
            Err(e) => break Some(e),
        }
    };
    if let Some(e) = &error {
        tokens.push(Token {
            tok: Tok::Error,
            pos: e.pos,
            end: e.pos,
        });
    }
    let end = text.len() as Pos;
    tokens.push(Token {
        tok: Tok::End,
        pos: end,
        end,
    });
    Ok(Lexed { tokens, error })
}

struct Lexer<'a> {
    text: &'a str,
    b: &'a [u8],
    /// Always at a character boundary between tokens: only ASCII is consumed outside strings
    /// and comments, and those end on ASCII delimiters.
    i: usize,
}

impl Lexer<'_> {
    /// The byte `k` ahead, or 0 past the end (0 matches nothing the lexer looks for).
    fn at(&self, k: usize) -> u8 {
        self.b.get(self.i + k).copied().unwrap_or(0)
    }

    fn error(&self, pos: usize, message: impl Into<String>) -> Diagnostic {
        Diagnostic::new(pos as Pos, message)
    }

    fn skip_trivia(&mut self) -> Result<(), Diagnostic> {
        loop {
            // Most bytes of a file are indentation: skip white space in a loop of its own.
            while matches!(
                self.b.get(self.i),
                Some(b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c)
            ) {
                self.i += 1;
            }
            match (self.at(0), self.at(1)) {
                (b'(', b'*') => self.skip_to("*)", 2, "comment")?,
                (b'/', b'*') => self.skip_to("*/", 2, "comment")?,
                (b'{', _) => self.skip_to("}", 1, "pragma")?,
                (b'/', b'/') => {
                    self.i = match self.b[self.i..].iter().position(|&c| c == b'\n') {
                        Some(n) => self.i + n + 1,
                        None => self.b.len(),
                    };
                }
                _ => return Ok(()),
            }
        }
    }

    /// Skips past `close`, looked for after the `open_len` bytes that open a comment or pragma.
    fn skip_to(&mut self, close: &str, open_len: usize, what: &str) -> Result<(), Diagnostic> {
        let start = self.i;
        let rest = self.text.get(start + open_len..).unwrap_or("");
        match rest.find(close) {
            Some(n) => {
                self.i = start + open_len + n + close.len();
                Ok(())
            }
            None => Err(self.error(
                start,
                format!("the {what} that starts here is never closed: add '{close}'"),
            )),
        }
    }

    fn token(&mut self) -> Result<Tok, Diagnostic> {
        match self.at(0) {
            b'A'..=b'Z' | b'a'..=b'z' | b'_' => self.word(),
            b'0'..=b'9' => self.number(),
            b'\'' => self.string().map(|()| Tok::Str),
            b'"' => Err(self.error(self.i, WSTRING)),
            b'%' => self.address(),
            _ => self.symbol(),
        }
    }

    /// A name, a keyword, or a typed literal (`INT#5`).
    fn word(&mut self) -> Result<Tok, Diagnostic> {
        let start = self.i;
        self.name()?;
        if self.at(0) == b'#' {
            return self.typed(start);
        }
        Ok(keyword(&self.b[start..self.i]).map_or(Tok::Ident, Tok::Kw))
    }

    /// Scans a name, refusing what MATIEC refuses (`a__b`, `a_`).
    fn name(&mut self) -> Result<(), Diagnostic> {
        let start = self.i;
        let mut valid = true;
        let mut underscore = false;
        while let Some(&c) = self.b.get(self.i) {
            if c == b'_' {
                valid &= !underscore;
                underscore = true;
            } else if c.is_ascii_alphanumeric() {
                underscore = false;
            } else {
                break;
            }
            self.i += 1;
        }
        if !valid || underscore {
            return Err(self.error(
                start,
                format!(
                    "'{}' is not a name: IEC 61131-3 allows letters, digits and single underscores, with no '__' and no '_' at the end; rename it",
                    self.text.get(start..self.i).unwrap_or("")
                ),
            ));
        }
        Ok(())
    }

    /// The rest of a typed literal, `self.i` at the `#` after its prefix.
    fn typed(&mut self, start: usize) -> Result<Tok, Diagnostic> {
        let prefix = self.text.get(start..self.i).unwrap_or("");
        let mut buf = [0; KEYWORD_MAX];
        let kind = match upper(prefix.as_bytes(), &mut buf) {
            Some(b"T" | b"TIME" | b"LT" | b"LTIME") => Tok::Time,
            Some(
                b"D" | b"DATE" | b"LD" | b"LDATE" | b"TOD" | b"TIME_OF_DAY" | b"LTOD"
                | b"LTIME_OF_DAY" | b"DT" | b"DATE_AND_TIME" | b"LDT" | b"LDATE_AND_TIME",
            ) => return Err(self.error(start, DATES)),
            Some(b"WSTRING" | b"WCHAR") => return Err(self.error(start, WSTRING)),
            _ => Tok::Typed,
        };
        self.i += 1;
        if kind == Tok::Time {
            if matches!(self.at(0), b'+' | b'-') {
                self.i += 1;
            }
            let body = self.i;
            while self.at(0).is_ascii_alphanumeric()
                || self.at(0) == b'_'
                || (self.at(0) == b'.' && self.at(1).is_ascii_digit())
            {
                self.i += 1;
            }
            if self.i == body {
                return Err(self.error(
                    start,
                    format!("expected a duration after '{prefix}#', such as {prefix}#1s500ms"),
                ));
            }
            return Ok(Tok::Time);
        }
        match self.at(0) {
            b'\'' => self.string()?,
            b'+' | b'-' if self.at(1).is_ascii_digit() => {
                self.i += 1;
                self.number()?;
            }
            b'0'..=b'9' => {
                self.number()?;
            }
            b'A'..=b'Z' | b'a'..=b'z' | b'_' => self.name()?,
            _ => {
                return Err(self.error(
                    start,
                    format!(
                        "expected a value right after '{prefix}#' (no spaces), such as INT#-5, BOOL#TRUE or Color#Red"
                    ),
                ))
            }
        }
        Ok(Tok::Typed)
    }

    /// A number: `5`, `1_000`, `16#FF`, `1.5`, `1.0E-3`.
    fn number(&mut self) -> Result<Tok, Diagnostic> {
        let start = self.i;
        self.digits(10)?;
        if self.at(0) == b'#' {
            let base = match self.text.get(start..self.i) {
                Some("2") => 2,
                Some("8") => 8,
                Some("16") => 16,
                other => {
                    return Err(self.error(
                        start,
                        format!(
                            "'{}#' is not a base: IEC 61131-3 has 2#, 8# and 16#",
                            other.unwrap_or("")
                        ),
                    ))
                }
            };
            self.i += 1;
            self.digits(base)?;
            self.no_letter_after(start)?;
            return Ok(Tok::Int);
        }
        let mut tok = Tok::Int;
        if self.at(0) == b'.' && self.at(1).is_ascii_digit() {
            self.i += 1;
            self.digits(10)?;
            tok = Tok::Real;
        }
        if matches!(self.at(0), b'e' | b'E') {
            if tok == Tok::Int {
                let digits = self.text.get(start..self.i).unwrap_or("");
                return Err(self.error(
                    start,
                    format!("a REAL literal needs a '.' and a fraction: write {digits}.0E…"),
                ));
            }
            self.i += 1;
            if matches!(self.at(0), b'+' | b'-') {
                self.i += 1;
            }
            self.digits(10)?;
        }
        self.no_letter_after(start)?;
        Ok(tok)
    }

    /// Digits of `base` with single underscores between them; at least one digit.
    fn digits(&mut self, base: u32) -> Result<(), Diagnostic> {
        let start = self.i;
        while self.at(0).is_ascii_digit()
            || self.at(0) == b'_'
            || (base == 16 && self.at(0).is_ascii_alphabetic())
        {
            self.i += 1;
        }
        let run = &self.b[start..self.i];
        if run.is_empty() {
            let found = self.describe_here();
            return Err(self.error(
                self.i,
                format!("expected a digit in base {base}, found {found}"),
            ));
        }
        if run[0] == b'_' || run.windows(2).any(|w| w == b"__") || run.last() == Some(&b'_') {
            return Err(self.error(
                start,
                "an underscore in a number must stand between two digits",
            ));
        }
        if let Some(bad) = run
            .iter()
            .position(|&c| c != b'_' && !char::from(c).is_digit(base))
        {
            return Err(self.error(
                start + bad,
                format!("'{}' is not a digit in base {base}", char::from(run[bad])),
            ));
        }
        Ok(())
    }

    fn no_letter_after(&self, start: usize) -> Result<(), Diagnostic> {
        if self.at(0).is_ascii_alphanumeric() || self.at(0) == b'_' {
            let mut end = self.i;
            while self
                .b
                .get(end)
                .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_')
            {
                end += 1;
            }
            return Err(self.error(
                start,
                format!(
                    "'{}' is not a number: a number cannot run into letters (a duration is written T#…)",
                    self.text.get(start..end).unwrap_or("")
                ),
            ));
        }
        Ok(())
    }

    /// A single-quoted string, `self.i` at its opening quote.
    fn string(&mut self) -> Result<(), Diagnostic> {
        let start = self.i;
        self.i += 1;
        loop {
            let Some(&c) = self.b.get(self.i) else {
                return Err(self.error(start, "the string that starts here is never closed: add '"));
            };
            match c {
                b'\'' => {
                    self.i += 1;
                    return Ok(());
                }
                b'\n' | b'\r' => {
                    return Err(self.error(
                        start,
                        "the string that starts here is not closed on its line: close it with ' (write $N for a line break inside a string)",
                    ))
                }
                b'$' => {
                    let next = self.at(1);
                    match next.to_ascii_uppercase() {
                        b'$' | b'\'' | b'"' | b'L' | b'N' | b'P' | b'R' | b'T' => self.i += 2,
                        _ if next.is_ascii_hexdigit() && self.at(2).is_ascii_hexdigit() => {
                            self.i += 3;
                        }
                        _ => {
                            let shown: String = self
                                .text
                                .get(self.i..)
                                .unwrap_or("")
                                .chars()
                                .take(2)
                                .collect();
                            return Err(self.error(
                                self.i,
                                format!("'{shown}' is not an escape: write $$, $', $L, $N, $P, $R, $T or $ and two hex digits"),
                            ));
                        }
                    }
                }
                _ => self.i += 1,
            }
        }
    }

    /// A direct address: `%IX0.0`, `%QW1`, `%MD10`.
    fn address(&mut self) -> Result<Tok, Diagnostic> {
        let start = self.i;
        self.i += 1;
        if !matches!(self.at(0).to_ascii_uppercase(), b'I' | b'Q' | b'M') {
            return Err(self.error(
                start,
                "expected I, Q or M after '%' (a direct address such as %IX0.0)",
            ));
        }
        self.i += 1;
        if matches!(
            self.at(0).to_ascii_uppercase(),
            b'X' | b'B' | b'W' | b'D' | b'L'
        ) {
            self.i += 1;
        }
        if self.at(0) == b'*' {
            return Err(self.error(
                start,
                "an address left open (%I*) is not supported: write the full address, as %IX0.0",
            ));
        }
        self.digits(10)?;
        while self.at(0) == b'.' && self.at(1).is_ascii_digit() {
            self.i += 1;
            self.digits(10)?;
        }
        self.no_letter_after(start)?;
        Ok(Tok::Address)
    }

    fn symbol(&mut self) -> Result<Tok, Diagnostic> {
        let (tok, len) = match (self.at(0), self.at(1)) {
            (b':', b'=') => (Tok::Assign, 2),
            (b':', _) => (Tok::Colon, 1),
            (b'=', b'>') => (Tok::Arrow, 2),
            (b'=', _) => (Tok::Rel(Rel::Eq), 1),
            (b'<', b'=') => (Tok::Rel(Rel::Le), 2),
            (b'<', b'>') => (Tok::Rel(Rel::Ne), 2),
            (b'<', _) => (Tok::Rel(Rel::Lt), 1),
            (b'>', b'=') => (Tok::Rel(Rel::Ge), 2),
            (b'>', _) => (Tok::Rel(Rel::Gt), 1),
            (b'*', b'*') => (Tok::Power, 2),
            (b'*', _) => (Tok::Star, 1),
            (b'.', b'.') => (Tok::DotDot, 2),
            (b'.', _) => (Tok::Dot, 1),
            (b'/', _) => (Tok::Slash, 1),
            (b'(', _) => (Tok::LParen, 1),
            (b')', _) => (Tok::RParen, 1),
            (b'[', _) => (Tok::LBracket, 1),
            (b']', _) => (Tok::RBracket, 1),
            (b',', _) => (Tok::Comma, 1),
            (b';', _) => (Tok::Semi, 1),
            (b'+', _) => (Tok::Plus, 1),
            (b'-', _) => (Tok::Minus, 1),
            (b'&', _) => (Tok::Amp, 1),
            (b'^', _) => (Tok::Caret, 1),
            (b'?', b'=') => {
                return Err(self.error(
                    self.i,
                    "the assignment attempt '?=' is not supported: it works on references, which are not supported",
                ))
            }
            _ => {
                let found = self.describe_here();
                return Err(self.error(self.i, format!("unexpected character {found}")));
            }
        };
        self.i += len;
        Ok(tok)
    }

    /// The character at `self.i`, quoted, for messages.
    fn describe_here(&self) -> String {
        match self.text.get(self.i..).and_then(|s| s.chars().next()) {
            Some(c) if c.is_control() => format!("{:?}", c),
            Some(c) => format!("'{c}'"),
            None => "the end of the text".to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{keyword, lex, Kw, Tok};

    #[test]
    fn every_keyword_is_found_in_any_case_and_nothing_else() {
        for &kw in Kw::ALL {
            assert_eq!(keyword(kw.text().as_bytes()), Some(kw));
            assert_eq!(keyword(kw.text().to_lowercase().as_bytes()), Some(kw));
        }
        assert_eq!(keyword(b"IFF"), None);
        assert_eq!(keyword(b"END_"), None);
        assert_eq!(keyword(b""), None);
        assert_eq!(keyword(b"A_VERY_LONG_NAME_INDEED_BEYOND_ANY_KEYWORD"), None);
    }

    #[test]
    fn tokens_carry_their_spans() {
        let text = "x := a.b[1] ** 2; // done";
        let kinds: Vec<(Tok, &str)> = lex(text)
            .expect("few tokens")
            .tokens
            .iter()
            .map(|t| (t.tok, &text[t.pos as usize..t.end as usize]))
            .collect();
        assert_eq!(
            kinds,
            [
                (Tok::Ident, "x"),
                (Tok::Assign, ":="),
                (Tok::Ident, "a"),
                (Tok::Dot, "."),
                (Tok::Ident, "b"),
                (Tok::LBracket, "["),
                (Tok::Int, "1"),
                (Tok::RBracket, "]"),
                (Tok::Power, "**"),
                (Tok::Int, "2"),
                (Tok::Semi, ";"),
                (Tok::End, ""),
            ]
        );
    }

    #[test]
    fn a_range_after_an_integer_is_not_a_real() {
        let text = "1..5";
        let kinds: Vec<Tok> = lex(text)
            .expect("few tokens")
            .tokens
            .iter()
            .map(|t| t.tok)
            .collect();
        assert_eq!(kinds, [Tok::Int, Tok::DotDot, Tok::Int, Tok::End]);
    }
}
