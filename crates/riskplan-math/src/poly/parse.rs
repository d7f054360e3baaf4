//! Parser for the polynomial text of scene format v1 (`docs/formats.md`):
//! numbers (`0.3`, `1e-3`, `37/300`), identifiers, `+ - * ^`, parentheses, unary
//! minus; `^` takes a non-negative integer literal; `/` divides by a constant only.
//!
//! Grammar (precedence climbing; `-x^2` is `-(x^2)`):
//! ```text
//! expr   := term (('+' | '-') term)*
//! term   := unary (('*' | '/') unary)*
//! unary  := ('-' | '+') unary | power
//! power  := atom ('^' INTEGER)?
//! atom   := NUMBER | IDENT | '(' expr ')'
//! ```
//! Numbers are read exactly as rationals (docs/design.md §1.4). Every error names the
//! column (1-based character position) and what was expected there.

use super::ring::parse_decimal;
use super::{Poly, Var};
use num_rational::BigRational;
use num_traits::Zero;
use thiserror::Error;

/// Largest exponent literal accepted after `^`. A guard against input that would
/// expand to an enormous polynomial (`(x+y+z)^1000`); scene polynomials of the
/// paper have degree ≤ 5, and contours double that.
pub const MAX_EXPONENT: u32 = 32;

/// Deepest nesting of parentheses and unary signs. The parser recurses once per
/// level, so this bounds its stack use (2000 nested parentheses would overflow a
/// worker thread's stack); written polynomials need a handful of levels.
pub const MAX_NESTING: usize = 64;

/// Largest total degree of any subexpression while parsing and expanding. Checked
/// *before* a product or power is formed, so nested powers such as `((x+1)^32)^32`
/// are refused without being expanded. Scenes allow degree 8 in (x, t) and 8 per
/// parameter after expansion (`scene::MAX_OBSTACLE_DEGREE`); intermediate results may
/// be larger before terms cancel, hence the margin.
pub const MAX_PARSE_DEGREE: u32 = 64;

/// Most terms of any intermediate polynomial while parsing (a scene obstacle may
/// have at most `scene::MAX_TERMS` = 2000 after expansion).
pub const MAX_PARSE_TERMS: usize = 10_000;

/// Budget of term-by-term products for one polynomial text: a product of polynomials
/// with `a` and `b` terms costs `a·b` (about 2 µs each in exact arithmetic while the
/// coefficients fit a machine word, and more, see [`product_cost`], when they do
/// not), so well under a tenth of a second (fuzzing found 0.7 s at 100 000 on a
/// loaded machine); every polynomial of the paper needs under a thousand, and a
/// 500-term obstacle (the scene limit) as a product of a 50-term and a 10-term
/// factor needs 500. A caller that parses many texts shares one budget among them
/// with [`parse_with_budget`].
pub const MAX_PARSE_WORK: usize = 25_000;

/// The work of the product of `a` and `b` in units of [`MAX_PARSE_WORK`]: `a·b` term
/// products, each weighted by the size of the coefficients multiplied, `(la + lb)²/4`
/// with `la`, `lb` the largest coefficient sizes in 64-bit words (numerator plus
/// denominator); multiplying and reducing big rationals costs about that. Word-sized
/// coefficients weigh 1.
pub fn product_cost(a: &Poly<BigRational>, b: &Poly<BigRational>) -> usize {
    fn words(p: &Poly<BigRational>) -> usize {
        let bits = p.terms().map(|(_, c)| c.numer().bits() + c.denom().bits()).max().unwrap_or(0);
        1 + (bits / 64) as usize
    }
    let (la, lb) = (words(a), words(b));
    let weight = ((la + lb) * (la + lb)).div_ceil(4);
    a.len().saturating_mul(b.len()).saturating_mul(weight)
}

/// A parse or resolution error in polynomial text, with its 1-based column.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PolyError {
    /// A token other than what the grammar allows here.
    #[error("column {col}: expected {expected}, found {found}")]
    Unexpected {
        /// 1-based column.
        col: usize,
        /// What the grammar allows here.
        expected: String,
        /// What is there.
        found: String,
    },
    /// An identifier the resolver does not know.
    #[error("column {col}: {message}")]
    UnknownVariable {
        /// 1-based column.
        col: usize,
        /// Why the name is not accepted (from the resolver).
        message: String,
    },
    /// `/` followed by something that is not a nonzero constant.
    #[error("column {col}: '/' must be followed by a nonzero numeric constant")]
    BadDivisor {
        /// 1-based column.
        col: usize,
    },
    /// `^` with an exponent above [`MAX_EXPONENT`].
    #[error("column {col}: exponent {exp} is larger than the limit {MAX_EXPONENT}")]
    ExponentTooLarge {
        /// 1-based column.
        col: usize,
        /// The exponent written.
        exp: String,
    },
    /// Parentheses or signs nested deeper than [`MAX_NESTING`].
    #[error("column {col}: nesting deeper than the limit {MAX_NESTING}")]
    TooDeep {
        /// 1-based column.
        col: usize,
    },
    /// Expansion beyond [`MAX_PARSE_DEGREE`], [`MAX_PARSE_TERMS`] or [`MAX_PARSE_WORK`].
    #[error("column {col}: expanding the polynomial exceeds the limit of {limit} ({what})")]
    TooLarge {
        /// 1-based column of the operator.
        col: usize,
        /// Which limit (`degree`, `terms` or `work`).
        what: &'static str,
        /// The limit.
        limit: usize,
    },
    /// A malformed number literal (or one beyond `MAX_DECIMAL_DIGITS` digits or an
    /// exponent beyond ±`MAX_DECIMAL_EXPONENT`).
    #[error("column {col}: malformed or too large number '{text}'")]
    BadNumber {
        /// 1-based column.
        col: usize,
        /// The literal.
        text: String,
    },
}

/// Maps identifiers to variables; returns a message when a name is not allowed.
pub type VarResolver<'a> = dyn FnMut(&str) -> Result<Var, String> + 'a;

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Num(String),
    Ident(String),
    Op(char),
    End,
}

struct Parser<'a, 'r> {
    toks: Vec<(Tok, usize)>,
    pos: usize,
    resolve: &'r mut VarResolver<'a>,
    /// Current nesting of parentheses and signs.
    depth: usize,
    /// Term products still allowed.
    budget: usize,
    /// The budget at the start (for the error message).
    budget_start: usize,
}

fn describe(t: &Tok) -> String {
    match t {
        Tok::Num(s) => format!("number '{s}'"),
        Tok::Ident(s) => format!("identifier '{s}'"),
        Tok::Op(c) => format!("'{c}'"),
        Tok::End => "end of text".to_string(),
    }
}

fn lex(text: &str) -> Result<Vec<(Tok, usize)>, PolyError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let col = i + 1;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit() || c == '.' {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                let save = i;
                i += 1;
                if i < chars.len() && (chars[i] == '+' || chars[i] == '-') {
                    i += 1;
                }
                if i < chars.len() && chars[i].is_ascii_digit() {
                    while i < chars.len() && chars[i].is_ascii_digit() {
                        i += 1;
                    }
                } else {
                    i = save; // `2e` followed by non-digit: let the 'e' be an identifier error later
                }
            }
            let s: String = chars[start..i].iter().collect();
            if parse_decimal(&s).is_none() {
                return Err(PolyError::BadNumber { col, text: s });
            }
            out.push((Tok::Num(s), col));
        } else if c.is_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push((Tok::Ident(chars[start..i].iter().collect()), col));
        } else if "+-*/^()".contains(c) {
            out.push((Tok::Op(c), col));
            i += 1;
        } else {
            return Err(PolyError::Unexpected {
                col,
                expected: "a number, identifier, operator or parenthesis".into(),
                found: format!("'{c}'"),
            });
        }
    }
    out.push((Tok::End, chars.len() + 1));
    Ok(out)
}

impl Parser<'_, '_> {
    fn peek(&self) -> &(Tok, usize) {
        &self.toks[self.pos]
    }

    fn next(&mut self) -> (Tok, usize) {
        let t = self.toks[self.pos].clone();
        if self.pos + 1 < self.toks.len() {
            self.pos += 1;
        }
        t
    }

    fn unexpected(&self, expected: &str) -> PolyError {
        let (t, col) = self.peek();
        PolyError::Unexpected { col: *col, expected: expected.into(), found: describe(t) }
    }

    fn expr(&mut self) -> Result<Poly<BigRational>, PolyError> {
        let mut acc = self.term()?;
        loop {
            match self.peek().0 {
                Tok::Op('+') => {
                    let col = self.next().1;
                    let rhs = self.term()?;
                    acc = self.checked_terms(acc.add(&rhs), col)?;
                }
                Tok::Op('-') => {
                    let col = self.next().1;
                    let rhs = self.term()?;
                    acc = self.checked_terms(acc.sub(&rhs), col)?;
                }
                _ => return Ok(acc),
            }
        }
    }

    fn term(&mut self) -> Result<Poly<BigRational>, PolyError> {
        let mut acc = self.unary()?;
        loop {
            match self.peek().0 {
                Tok::Op('*') => {
                    let col = self.next().1;
                    let rhs = self.unary()?;
                    acc = self.checked_mul(&acc, &rhs, col)?;
                }
                Tok::Op('/') => {
                    let col = self.next().1;
                    let d = self.unary()?;
                    let c = d.constant_term();
                    if d.len() > 1 || (d.len() == 1 && d.degree() > 0) || c.is_zero() {
                        return Err(PolyError::BadDivisor { col });
                    }
                    // scaling every term costs like a product with a one-term polynomial
                    // (found by fuzzing: a hundred divisions of a 528-term power took
                    // 2.5 s while its expansion was within the budget)
                    self.charge(product_cost(&acc, &d), col)?;
                    acc = acc.scale(&(BigRational::from_integer(1.into()) / c));
                }
                _ => return Ok(acc),
            }
        }
    }

    /// Signs are read in a loop (no recursion), but count towards the nesting limit.
    fn unary(&mut self) -> Result<Poly<BigRational>, PolyError> {
        let mut negate = false;
        let mut signs = 0;
        while let (Tok::Op(c @ ('-' | '+')), col) = self.peek().clone() {
            signs += 1;
            if self.depth + signs > MAX_NESTING {
                return Err(PolyError::TooDeep { col });
            }
            negate ^= c == '-';
            self.next();
        }
        self.depth += signs;
        let p = self.power();
        self.depth -= signs;
        let p = p?;
        Ok(if negate { p.neg() } else { p })
    }

    /// `a·b`, refused before it is formed when it would exceed the degree, terms or
    /// work limits.
    fn checked_mul(
        &mut self,
        a: &Poly<BigRational>,
        b: &Poly<BigRational>,
        col: usize,
    ) -> Result<Poly<BigRational>, PolyError> {
        if a.degree() as u64 + b.degree() as u64 > MAX_PARSE_DEGREE as u64 {
            return Err(PolyError::TooLarge { col, what: "degree", limit: MAX_PARSE_DEGREE as usize });
        }
        self.charge(product_cost(a, b), col)?;
        self.checked_terms(a.mul(b), col)
    }

    /// Takes `cost` from the work budget, or refuses the text (`TooLarge`, `work`).
    fn charge(&mut self, cost: usize, col: usize) -> Result<(), PolyError> {
        if cost > self.budget {
            return Err(PolyError::TooLarge { col, what: "work", limit: self.budget_start });
        }
        self.budget -= cost;
        Ok(())
    }

    fn checked_terms(&self, p: Poly<BigRational>, col: usize) -> Result<Poly<BigRational>, PolyError> {
        if p.len() > MAX_PARSE_TERMS {
            return Err(PolyError::TooLarge { col, what: "terms", limit: MAX_PARSE_TERMS });
        }
        Ok(p)
    }

    fn power(&mut self) -> Result<Poly<BigRational>, PolyError> {
        let base = self.atom()?;
        if self.peek().0 != Tok::Op('^') {
            return Ok(base);
        }
        self.next();
        let (tok, col) = self.next();
        match tok {
            Tok::Num(s) if s.bytes().all(|b| b.is_ascii_digit()) => {
                let e: u32 = match s.parse() {
                    Ok(e) if e <= MAX_EXPONENT => e,
                    _ => return Err(PolyError::ExponentTooLarge { col, exp: s }),
                };
                if self.peek().0 == Tok::Op('^') {
                    return Err(self.unexpected("an operator other than a second '^' (write (a^b)^c)"));
                }
                if base.degree() as u64 * e as u64 > MAX_PARSE_DEGREE as u64 {
                    return Err(PolyError::TooLarge { col, what: "degree", limit: MAX_PARSE_DEGREE as usize });
                }
                // repeated multiplication, each step within the limits
                let mut acc = Poly::constant(BigRational::from_integer(1.into()));
                for _ in 0..e {
                    acc = self.checked_mul(&acc, &base, col)?;
                }
                Ok(acc)
            }
            other => Err(PolyError::Unexpected {
                col,
                expected: "a non-negative integer exponent after '^'".into(),
                found: describe(&other),
            }),
        }
    }

    fn atom(&mut self) -> Result<Poly<BigRational>, PolyError> {
        let (tok, col) = self.peek().clone();
        match tok {
            Tok::Num(s) => {
                self.next();
                let v = parse_decimal(&s).ok_or(PolyError::BadNumber { col, text: s })?;
                Ok(Poly::constant(v))
            }
            Tok::Ident(name) => {
                self.next();
                let v = (self.resolve)(&name).map_err(|message| PolyError::UnknownVariable { col, message })?;
                Ok(Poly::var(v))
            }
            Tok::Op('(') => {
                if self.depth >= MAX_NESTING {
                    return Err(PolyError::TooDeep { col });
                }
                self.next();
                self.depth += 1;
                let inner = self.expr();
                self.depth -= 1;
                let inner = inner?;
                if self.peek().0 != Tok::Op(')') {
                    return Err(self.unexpected("')' or an operator"));
                }
                self.next();
                Ok(inner)
            }
            _ => Err(self.unexpected("a number, an identifier or '('")),
        }
    }
}

/// Parses polynomial text; `resolve` maps each identifier to a variable. Expansion
/// may spend at most [`MAX_PARSE_WORK`] term products.
pub fn parse(text: &str, resolve: &mut VarResolver<'_>) -> Result<Poly<BigRational>, PolyError> {
    let mut budget = MAX_PARSE_WORK;
    parse_with_budget(text, resolve, &mut budget)
}

/// [`parse`] with a work budget shared by several texts (a scene's obstacles): the
/// products spent are taken from `budget`, and the text is refused (`TooLarge`,
/// `work`) when it would need more than is left.
pub fn parse_with_budget(
    text: &str,
    resolve: &mut VarResolver<'_>,
    budget: &mut usize,
) -> Result<Poly<BigRational>, PolyError> {
    let toks = lex(text)?;
    let mut p = Parser { toks, pos: 0, resolve, depth: 0, budget: *budget, budget_start: *budget };
    let out = p.expr();
    *budget = p.budget;
    let out = out?;
    if p.peek().0 != Tok::End {
        return Err(p.unexpected("an operator ('+', '-', '*', '/', '^') or end of text"));
    }
    Ok(out)
}
