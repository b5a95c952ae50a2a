//! State predicates of `--reach` and `--always`: linear comparisons over place names, joined by
//! `&&`, `||`, `!` and parentheses, e.g. `P10 >= 2 && P20 == 0` or `!(2*buf + out > 5 || done)`.
//!
//! The parser reads the text once, left to right, with the shunting-yard algorithm: no recursion,
//! so a hostile input cannot exhaust the stack; the length ([`MAX_LEN`]) and the nesting of
//! parentheses ([`MAX_DEPTH`]) are bounded. The result is a postfix program evaluated with a small
//! stack of booleans. Every error names the column (1-based, in characters) where it was found.
//!
//! Grammar (`name` is a place id, or a place name that no other place bears; letters, digits, `_`
//! and `.`, or any text in double quotes):
//!
//! ```text
//! formula    := conjunction ("||" conjunction)*
//! conjunction:= literal ("&&" literal)*
//! literal    := "!" literal | "(" formula ")" | "true" | "false" | comparison
//! comparison := sum op sum            op := "<" | "<=" | "==" | "!=" | ">=" | ">"
//! sum        := ["-"] term (("+" | "-") term)*
//! term       := number | number "*" name | name
//! ```

use std::fmt;

use cetratus_net::{Net, PlaceIdx};

/// Longest predicate text accepted, in bytes.
pub const MAX_LEN: usize = 64 * 1024;
/// Deepest nesting of parentheses accepted.
pub const MAX_DEPTH: usize = 256;

/// A predicate that could not be read: what is wrong and at which column.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PredicateError {
    /// 1-based column, in characters.
    pub column: usize,
    /// What is wrong there, and what to write instead.
    pub message: String,
}

impl fmt::Display for PredicateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "at column {}: {}", self.column, self.message)
    }
}

impl std::error::Error for PredicateError {}

/// A comparison operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cmp {
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `==`
    Eq,
    /// `!=`
    Ne,
    /// `>=`
    Ge,
    /// `>`
    Gt,
}

/// `Σ coef·M(p) op rhs`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Atom {
    /// Coefficients per place (each place once, no zero).
    pub terms: Vec<(PlaceIdx, i64)>,
    /// The comparison.
    pub op: Cmp,
    /// The constant on the right.
    pub rhs: i64,
}

impl Atom {
    fn holds(&self, tokens: &impl Fn(PlaceIdx) -> u64) -> bool {
        let lhs: i128 = self
            .terms
            .iter()
            .map(|&(p, c)| i128::from(c) * i128::from(tokens(p)))
            .sum();
        let r = i128::from(self.rhs);
        match self.op {
            Cmp::Lt => lhs < r,
            Cmp::Le => lhs <= r,
            Cmp::Eq => lhs == r,
            Cmp::Ne => lhs != r,
            Cmp::Ge => lhs >= r,
            Cmp::Gt => lhs > r,
        }
    }
}

/// One step of the postfix program.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Step {
    /// Push the value of an atom.
    Atom(Atom),
    /// Push a constant.
    Const(bool),
    /// Negate the top.
    Not,
    /// Replace the two top values by their conjunction.
    And,
    /// Replace the two top values by their disjunction.
    Or,
}

/// A parsed predicate over the places of one net.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Predicate {
    /// The text it was read from.
    pub text: String,
    /// The postfix program.
    pub steps: Vec<Step>,
}

impl Predicate {
    /// Whether the predicate holds at the marking that `tokens` reads.
    pub fn holds(&self, tokens: impl Fn(PlaceIdx) -> u64) -> bool {
        let mut stack: Vec<bool> = Vec::with_capacity(8);
        for s in &self.steps {
            let v = match s {
                Step::Atom(a) => a.holds(&tokens),
                Step::Const(b) => *b,
                Step::Not => !stack.pop().unwrap_or(false),
                Step::And => {
                    let b = stack.pop().unwrap_or(false);
                    stack.pop().unwrap_or(false) && b
                }
                Step::Or => {
                    let b = stack.pop().unwrap_or(false);
                    stack.pop().unwrap_or(false) || b
                }
            };
            stack.push(v);
        }
        stack.pop().unwrap_or(false)
    }

    /// The negation (for `--always P`: search a marking where `!P` holds).
    pub fn negated(&self) -> Predicate {
        let mut steps = self.steps.clone();
        steps.push(Step::Not);
        Predicate {
            text: format!("!({})", self.text),
            steps,
        }
    }

    /// Places the predicate reads, one flag per place.
    pub fn support(&self, places: usize) -> Vec<bool> {
        let mut v = vec![false; places];
        for s in &self.steps {
            if let Step::Atom(a) = s {
                for &(p, _) in &a.terms {
                    v[p.index()] = true;
                }
            }
        }
        v
    }

    /// "Some place holds more than one token", over every place of the net.
    pub fn unsafe_marking(net: &Net) -> Predicate {
        let mut steps = vec![Step::Const(false)];
        for p in 0..net.num_places() {
            steps.push(Step::Atom(Atom {
                terms: vec![(PlaceIdx(p as u32), 1)],
                op: Cmp::Gt,
                rhs: 1,
            }));
            steps.push(Step::Or);
        }
        Predicate {
            text: "some place > 1".into(),
            steps,
        }
    }

    /// Reads `text` against the places of `net`.
    pub fn parse(text: &str, net: &Net) -> Result<Predicate, PredicateError> {
        Parser::new(text, net)?.run()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Tok<'a> {
    Num(u64),
    Name(&'a str),
    Op(Cmp),
    Plus,
    Minus,
    Star,
    And,
    Or,
    Not,
    Open,
    Close,
}

fn lex(text: &str) -> Result<Vec<(Tok<'_>, usize)>, PredicateError> {
    let col = |byte: usize| text[..byte].chars().count() + 1;
    let err = |byte: usize, m: String| PredicateError {
        column: col(byte),
        message: m,
    };
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        let two = b.get(i..i + 2);
        let (tok, len) = match c {
            b' ' | b'\t' | b'\n' | b'\r' => {
                i += 1;
                continue;
            }
            b'0'..=b'9' => {
                let end = b[i..]
                    .iter()
                    .position(|c| !c.is_ascii_digit())
                    .map_or(b.len(), |n| i + n);
                let n = text[i..end]
                    .parse::<u64>()
                    .ok()
                    .filter(|&n| n <= i64::MAX as u64);
                match n {
                    Some(n) => (Tok::Num(n), end - i),
                    None => {
                        return Err(err(i, format!("the number {} is too large", &text[i..end])))
                    }
                }
            }
            c if c.is_ascii_alphabetic() || c == b'_' => {
                let end = b[i..]
                    .iter()
                    .position(|c| !(c.is_ascii_alphanumeric() || matches!(c, b'_' | b'.')))
                    .map_or(b.len(), |n| i + n);
                (Tok::Name(&text[i..end]), end - i)
            }
            b'"' => {
                // A quoted place name, for ids with spaces or operators in them.
                let end = b[i + 1..].iter().position(|&c| c == b'"').ok_or_else(|| {
                    err(
                        i,
                        "this quote is never closed; end the place name with \"".into(),
                    )
                })?;
                (Tok::Name(&text[i + 1..i + 1 + end]), end + 2)
            }
            _ => match two {
                Some(b"&&") => (Tok::And, 2),
                Some(b"||") => (Tok::Or, 2),
                Some(b"<=") => (Tok::Op(Cmp::Le), 2),
                Some(b">=") => (Tok::Op(Cmp::Ge), 2),
                Some(b"==") => (Tok::Op(Cmp::Eq), 2),
                Some(b"!=") => (Tok::Op(Cmp::Ne), 2),
                _ => match c {
                    b'<' => (Tok::Op(Cmp::Lt), 1),
                    b'>' => (Tok::Op(Cmp::Gt), 1),
                    b'+' => (Tok::Plus, 1),
                    b'-' => (Tok::Minus, 1),
                    b'*' => (Tok::Star, 1),
                    b'!' => (Tok::Not, 1),
                    b'(' => (Tok::Open, 1),
                    b')' => (Tok::Close, 1),
                    b'=' => {
                        return Err(err(
                            i,
                            "a single `=` is not a comparison; write `==`".into(),
                        ))
                    }
                    b'&' => return Err(err(i, "write `&&` for \"and\"".into())),
                    b'|' => return Err(err(i, "write `||` for \"or\"".into())),
                    _ => {
                        let ch = text[i..].chars().next().unwrap_or('?');
                        return Err(err(
                            i,
                            format!(
                                "unexpected character {ch:?}; a predicate uses place names, \
                                 numbers, + - *, < <= == != >= >, && || ! and parentheses"
                            ),
                        ));
                    }
                },
            },
        };
        out.push((tok, i));
        i += len;
    }
    Ok(out)
}

/// Operators waiting on the shunting-yard stack.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Pending {
    Not,
    And,
    Or,
    Open(usize),
}

struct Parser<'a> {
    text: &'a str,
    net: &'a Net,
    toks: Vec<(Tok<'a>, usize)>,
    pos: usize,
}

impl<'a> Parser<'a> {
    fn new(text: &'a str, net: &'a Net) -> Result<Self, PredicateError> {
        if text.len() > MAX_LEN {
            return Err(PredicateError {
                column: 1,
                message: format!(
                    "the predicate is {} bytes long, more than the {MAX_LEN} accepted",
                    text.len()
                ),
            });
        }
        Ok(Parser {
            text,
            net,
            toks: lex(text)?,
            pos: 0,
        })
    }

    fn col(&self, byte: usize) -> usize {
        self.text[..byte].chars().count() + 1
    }

    fn err<T>(&self, byte: usize, m: impl Into<String>) -> Result<T, PredicateError> {
        Err(PredicateError {
            column: self.col(byte),
            message: m.into(),
        })
    }

    fn end_byte(&self) -> usize {
        self.text.len()
    }

    fn peek(&self) -> Option<(Tok<'a>, usize)> {
        self.toks.get(self.pos).copied()
    }

    fn place(&self, name: &str, at: usize) -> Result<PlaceIdx, PredicateError> {
        if let Some(p) = self.net.place_by_id(name) {
            return Ok(p);
        }
        let named: Vec<usize> = (0..self.net.num_places())
            .filter(|&p| self.net.places()[p].name.as_deref() == Some(name))
            .collect();
        match named[..] {
            [p] => Ok(PlaceIdx(p as u32)),
            [] => {
                let some: Vec<&str> = self
                    .net
                    .places()
                    .iter()
                    .take(5)
                    .map(|p| p.id.as_str())
                    .collect();
                self.err(
                    at,
                    format!(
                        "the net has no place {name:?}; use a place id or a name borne by one \
                         place (ids here: {}{})",
                        some.join(", "),
                        if self.net.num_places() > 5 {
                            ", …"
                        } else {
                            ""
                        }
                    ),
                )
            }
            _ => self.err(
                at,
                format!(
                    "{} places are named {name:?}; use the place id instead",
                    named.len()
                ),
            ),
        }
    }

    /// `sum` at the cursor, added into `acc` with `sign`; returns the constant part.
    fn sum(&mut self, acc: &mut Vec<(PlaceIdx, i64)>, sign: i64) -> Result<i64, PredicateError> {
        let mut konst: i64 = 0;
        let mut neg = false;
        if let Some((Tok::Minus, _)) = self.peek() {
            neg = true;
            self.pos += 1;
        }
        loop {
            let s = if neg { -sign } else { sign };
            let overflow = |p: &Self, at| {
                p.err::<()>(at, "the coefficients are too large for 64-bit arithmetic")
            };
            match self.peek() {
                Some((Tok::Num(n), at)) => {
                    self.pos += 1;
                    if let Some((Tok::Star, _)) = self.peek() {
                        self.pos += 1;
                        match self.peek() {
                            Some((Tok::Name(name), nat)) => {
                                self.pos += 1;
                                let p = self.place(name, nat)?;
                                let c = (n as i64).checked_mul(s);
                                let Some(c) = c else {
                                    return overflow(self, at).map(|_| 0);
                                };
                                add_term(acc, p, c).map_or_else(|| overflow(self, at), Ok)?;
                            }
                            Some((_, a)) => return self.err(a, "expected a place name after `*`"),
                            None => {
                                return self.err(self.end_byte(), "expected a place name after `*`")
                            }
                        }
                    } else {
                        let Some(v) = (n as i64).checked_mul(s).and_then(|v| konst.checked_add(v))
                        else {
                            return overflow(self, at).map(|_| 0);
                        };
                        konst = v;
                    }
                }
                Some((Tok::Name(name), at)) if name != "true" && name != "false" => {
                    self.pos += 1;
                    let p = self.place(name, at)?;
                    add_term(acc, p, s).map_or_else(|| overflow(self, at), Ok)?;
                }
                Some((_, at)) => return self.err(at, "expected a number or a place name"),
                None => {
                    return self.err(
                        self.end_byte(),
                        "expected a number or a place name, found the end",
                    )
                }
            }
            match self.peek() {
                Some((Tok::Plus, _)) => {
                    neg = false;
                    self.pos += 1;
                }
                Some((Tok::Minus, _)) => {
                    neg = true;
                    self.pos += 1;
                }
                _ => return Ok(konst),
            }
        }
    }

    fn comparison(&mut self) -> Result<Atom, PredicateError> {
        let mut terms = Vec::new();
        let left = self.sum(&mut terms, 1)?;
        let op = match self.peek() {
            Some((Tok::Op(op), _)) => op,
            Some((_, at)) => return self.err(at, "expected a comparison (< <= == != >= >) here"),
            None => {
                return self.err(
                    self.end_byte(),
                    "expected a comparison (< <= == != >= >), found the end",
                )
            }
        };
        let at = self.peek().map_or(0, |t| t.1);
        self.pos += 1;
        let right = self.sum(&mut terms, -1)?;
        terms.retain(|&(_, c)| c != 0);
        // Σ left − Σ right op R − L, where the right sum was read negated (it returned −R).
        let Some(rhs) = right.checked_add(left).and_then(i64::checked_neg) else {
            return self.err(at, "the constants are too large for 64-bit arithmetic");
        };
        Ok(Atom { terms, op, rhs })
    }

    fn run(mut self) -> Result<Predicate, PredicateError> {
        let mut out: Vec<Step> = Vec::new();
        let mut ops: Vec<Pending> = Vec::new();
        let mut depth = 0usize;
        // Whether the next token must start an operand (true) or be an operator or `)` (false).
        let mut operand = true;
        let prec = |p: Pending| match p {
            Pending::Not => 3,
            Pending::And => 2,
            Pending::Or => 1,
            Pending::Open(_) => 0,
        };
        let emit = |p: Pending, out: &mut Vec<Step>| match p {
            Pending::Not => out.push(Step::Not),
            Pending::And => out.push(Step::And),
            Pending::Or => out.push(Step::Or),
            Pending::Open(_) => {}
        };
        if self.toks.is_empty() {
            return Err(PredicateError {
                column: 1,
                message: "the predicate is empty; e.g. `P1 >= 2 && P2 == 0`".into(),
            });
        }
        while let Some((tok, at)) = self.peek() {
            if operand {
                match tok {
                    Tok::Not => {
                        ops.push(Pending::Not);
                        self.pos += 1;
                    }
                    Tok::Open => {
                        depth += 1;
                        if depth > MAX_DEPTH {
                            return self.err(
                                at,
                                format!("parentheses nest deeper than {MAX_DEPTH} levels"),
                            );
                        }
                        ops.push(Pending::Open(at));
                        self.pos += 1;
                    }
                    Tok::Name("true") | Tok::Name("false") => {
                        out.push(Step::Const(tok == Tok::Name("true")));
                        self.pos += 1;
                        operand = false;
                    }
                    Tok::Num(_) | Tok::Name(_) | Tok::Minus => {
                        let a = self.comparison()?;
                        out.push(Step::Atom(a));
                        operand = false;
                    }
                    _ => {
                        return self.err(
                            at,
                            "expected a comparison such as `P1 >= 2`, `!`, `(`, true or false",
                        )
                    }
                }
            } else {
                let op = match tok {
                    Tok::And => Pending::And,
                    Tok::Or => Pending::Or,
                    Tok::Close => {
                        loop {
                            match ops.pop() {
                                Some(Pending::Open(_)) => break,
                                Some(p) => emit(p, &mut out),
                                None => return self.err(at, "this `)` closes no `(`"),
                            }
                        }
                        depth -= 1;
                        self.pos += 1;
                        continue;
                    }
                    _ => return self.err(at, "expected `&&`, `||`, `)` or the end here"),
                };
                while let Some(&top) = ops.last() {
                    if !matches!(top, Pending::Open(_)) && prec(top) >= prec(op) {
                        emit(top, &mut out);
                        ops.pop();
                    } else {
                        break;
                    }
                }
                ops.push(op);
                self.pos += 1;
                operand = true;
            }
        }
        if operand {
            return self.err(
                self.end_byte(),
                "the predicate ends where an operand is expected",
            );
        }
        while let Some(p) = ops.pop() {
            if let Pending::Open(at) = p {
                return self.err(at, "this `(` is never closed");
            }
            emit(p, &mut out);
        }
        Ok(Predicate {
            text: self.text.to_string(),
            steps: out,
        })
    }
}

/// Adds `c·p` to the terms; `None` on overflow.
fn add_term(acc: &mut Vec<(PlaceIdx, i64)>, p: PlaceIdx, c: i64) -> Option<()> {
    match acc.iter_mut().find(|e| e.0 == p) {
        Some(e) => e.1 = e.1.checked_add(c)?,
        None => acc.push((p, c)),
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cetratus_net::{NetBuilder, Place};

    fn net() -> Net {
        let mut b = NetBuilder::new("n");
        b.add_place(Place::new("P1", 0)).expect("place");
        let mut named = Place::new("p2", 0);
        named.name = Some("buffer".into());
        b.add_place(named).expect("place");
        b.build().expect("net")
    }

    fn eval(text: &str, m: [u64; 2]) -> bool {
        Predicate::parse(text, &net())
            .unwrap_or_else(|e| panic!("{text}: {e}"))
            .holds(|p| m[p.index()])
    }

    fn column(text: &str) -> usize {
        Predicate::parse(text, &net()).map_or_else(|e| e.column, |_| 0)
    }

    #[test]
    fn and_binds_tighter_than_or_and_not_tighter_than_both() {
        assert!(eval("P1 == 1 || P1 == 0 && buffer == 5", [1, 0]));
        assert!(!eval("(P1 == 1 || P1 == 0) && buffer == 5", [1, 0]));
        assert!(eval("!P1 == 1 && buffer == 0", [0, 0]));
        assert!(!eval("!(P1 == 0 && buffer == 0)", [0, 0]));
        assert!(eval("!!true", [0, 0]));
        assert!(!eval("false || false", [0, 0]));
    }

    #[test]
    fn sums_with_coefficients_compare_both_sides() {
        assert!(eval("2*P1 + buffer - 1 >= p2 + 3", [2, 7]));
        assert!(!eval("2*P1 + buffer - 1 > p2 + 3", [2, 7]));
        assert!(eval("-P1 < 0", [1, 0]));
        assert!(eval("P1 != buffer", [1, 0]));
        assert!(eval("\"P1\" <= 3", [3, 0]));
        assert!(eval("5 > P1 + p2", [2, 2]));
    }

    #[test]
    fn errors_name_the_column_where_reading_failed() {
        assert_eq!(column(""), 1);
        assert_eq!(column("P1 >"), 5);
        assert_eq!(column("P1 = 2"), 4);
        assert_eq!(column("P1 > 2 &&"), 10);
        assert_eq!(column("P1 > 2 & P1 < 3"), 8);
        assert_eq!(column("P1 > 2)"), 7);
        assert_eq!(column("((P1 > 2)"), 1);
        assert_eq!(column("P3 > 2"), 1);
        assert_eq!(column("P1 > 2 P1"), 8);
        assert_eq!(column("é > 2"), 1);
        assert_eq!(column("P1 > 2 && \"P1"), 11);
    }

    #[test]
    fn nesting_and_length_are_bounded() {
        let ok = format!("{}P1 == 0{}", "(".repeat(MAX_DEPTH), ")".repeat(MAX_DEPTH));
        assert!(eval(&ok, [0, 0]));
        let deep = format!(
            "{}P1 == 0{}",
            "(".repeat(MAX_DEPTH + 1),
            ")".repeat(MAX_DEPTH + 1)
        );
        assert_eq!(column(&deep), MAX_DEPTH + 1);
        let long = "P1 == 0 || ".repeat(MAX_LEN / 8);
        assert!(Predicate::parse(&long, &net()).is_err());
    }
}
