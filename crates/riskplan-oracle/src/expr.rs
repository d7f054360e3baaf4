//! The oracle's own parser and `f64` evaluator for polynomial text (the `poly` field of
//! a scene's obstacles), written from the grammar alone and sharing nothing with
//! riskplan's polynomial code.
//!
//! ```text
//! expr     := term (('+' | '-') term)*
//! term     := unary (('*' | '/') unary)*
//! unary    := ('-' | '+')* power
//! power    := atom ('^' exponent)?
//! exponent := INTEGER ('^' exponent)?        (right-associative: x^2^3 = x^(2^3) = x^8)
//! atom     := NUMBER | IDENT | '(' expr ')'
//! NUMBER   := digits with an optional '.', then optionally e|E, an optional sign, digits
//!             (0.3, 5., .5, 1e41, 1.5e-3)
//! IDENT    := a letter or '_', then letters, digits or '_'
//! ```
//!
//! Powers bind tighter than unary signs (`-x^2` is −(x²)); whitespace is ignored.
//! Division is plain `f64` division by whatever the denominator evaluates to (the
//! oracle evaluates, it does not expand). Identifiers may use Unicode letters, as the
//! scene format allows (`ω1`); ASCII names are the usual case. (The scene format refuses
//! a chained power `x^2^3`; this parser reads it right-associatively. Accepting more
//! than the product is harmless for an oracle.)
//!
//! Parsing is bounded: at most [`MAX_TEXT_LEN`] bytes, [`MAX_NESTING`] nested
//! parentheses and signs, exponents of at most [`MAX_EXPONENT`]. The tree keeps sums
//! and products as flat lists, so its depth is bounded by the nesting, not by the
//! number of terms: every recursive walk is shallow.
//!
//! [`Expr::bind`] compiles the tree against a list of variable names into a [`Bound`]
//! program: a flat instruction list for a small stack machine, with constant
//! subexpressions folded and leaf operands fused into the instruction that uses them
//! (a constant left operand of + or × is swapped to the right: IEEE addition and
//! multiplication are commutative bit for bit).
//! [`Bound::eval`] does not allocate (for programs whose stack fits [`INLINE_STACK`]
//! slots; [`Bound::eval_with`] takes a caller's buffer for any program). Compiled and
//! tree evaluation perform the same `f64` operations (up to the commutation of + and ×),
//! so they agree bit for bit, NaN payloads aside ([`Expr::eval`]).

use thiserror::Error;

/// Longest accepted text, in bytes.
pub const MAX_TEXT_LEN: usize = 100_000;
/// Deepest accepted nesting: each open parenthesis and each unary sign counts one level.
pub const MAX_NESTING: usize = 200;
/// Largest accepted exponent (after folding a right-associative chain `a^b^c`).
pub const MAX_EXPONENT: u32 = 64;
/// Stack slots [`Bound::eval`] keeps on the call stack; a program that needs more
/// evaluates with a heap buffer (one allocation per call), or without one through
/// [`Bound::eval_with`].
pub const INLINE_STACK: usize = 32;

/// Why a text does not parse, or does not bind.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ExprError {
    /// The text is longer than [`MAX_TEXT_LEN`] bytes.
    #[error("the text has {len} bytes, more than the limit {max}")]
    TooLong {
        /// Its length in bytes.
        len: usize,
        /// [`MAX_TEXT_LEN`].
        max: usize,
    },
    /// Parentheses and signs nested deeper than [`MAX_NESTING`].
    #[error("column {column}: nesting deeper than {max}")]
    TooDeep {
        /// 1-based column (in characters).
        column: usize,
        /// [`MAX_NESTING`].
        max: usize,
    },
    /// A character outside the grammar.
    #[error("column {column}: unexpected character {found:?}")]
    BadChar {
        /// 1-based column.
        column: usize,
        /// The character.
        found: char,
    },
    /// A malformed number, or one that is not a finite `f64`.
    #[error("column {column}: bad number {text:?}: {reason}")]
    BadNumber {
        /// 1-based column.
        column: usize,
        /// The number's text.
        text: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// Something else than what the grammar allows at this place.
    #[error("column {column}: expected {expected}, found {found}")]
    Expected {
        /// 1-based column (one past the end for the end of the text).
        column: usize,
        /// What the grammar allows here.
        expected: &'static str,
        /// What is there (a token's text, or "the end").
        found: String,
    },
    /// An exponent (after folding a chain) larger than [`MAX_EXPONENT`].
    #[error("column {column}: exponent larger than {max}")]
    ExponentTooLarge {
        /// 1-based column of the exponent.
        column: usize,
        /// [`MAX_EXPONENT`].
        max: u32,
    },
    /// [`Expr::bind`]: an identifier of the text that is not among the given names.
    #[error("unknown identifier {name:?}")]
    UnknownIdentifier {
        /// The identifier.
        name: String,
    },
}

/// A node of the expression tree. Sums and products are flat lists, so the tree is
/// only as deep as the text's nesting.
#[derive(Clone, Debug, PartialEq)]
enum Node {
    /// A number.
    Num(f64),
    /// An identifier: index into [`Expr::names`].
    Var(usize),
    /// −a.
    Neg(Box<Node>),
    /// a₀ ± a₁ ± …, left to right; `true` marks a subtracted term (the first is never).
    Sum(Vec<(bool, Node)>),
    /// a₀ ×/÷ a₁ ×/÷ …, left to right; `true` marks a divisor (the first is never).
    Product(Vec<(bool, Node)>),
    /// a^k.
    Pow(Box<Node>, u32),
}

/// A parsed polynomial text.
#[derive(Clone, Debug, PartialEq)]
pub struct Expr {
    root: Node,
    /// Distinct identifiers, in order of first appearance.
    names: Vec<String>,
}

/// `x^k` by binary powering (the same operations in every evaluator, independent of
/// the platform's `powi`). `x^0` is 1 for every x, as in a polynomial.
pub fn pow_u(x: f64, k: u32) -> f64 {
    if k == 2 {
        return x * x; // what the loop below computes (1·(x·x)), without the loop
    }
    let mut result = 1.0;
    let mut base = x;
    let mut k = k;
    while k > 0 {
        if k & 1 == 1 {
            result *= base;
        }
        k >>= 1;
        if k > 0 {
            base *= base;
        }
    }
    result
}

// ---------------------------------------------------------------------------------
// Lexer

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    /// A number: its text (validated) and value.
    Num(String, f64),
    Ident(String),
    Plus,
    Minus,
    Star,
    Slash,
    Caret,
    LParen,
    RParen,
}

impl Tok {
    fn describe(&self) -> String {
        match self {
            Tok::Num(s, _) => format!("number {s}"),
            Tok::Ident(s) => format!("identifier {s}"),
            Tok::Plus => "'+'".into(),
            Tok::Minus => "'-'".into(),
            Tok::Star => "'*'".into(),
            Tok::Slash => "'/'".into(),
            Tok::Caret => "'^'".into(),
            Tok::LParen => "'('".into(),
            Tok::RParen => "')'".into(),
        }
    }
}

/// A token and its 1-based column.
type Spanned = (Tok, usize);

fn is_ident_start(c: char) -> bool {
    c == '_' || c.is_alphabetic()
}

fn is_ident_continue(c: char) -> bool {
    c == '_' || c.is_alphanumeric()
}

fn lex(text: &str) -> Result<Vec<Spanned>, ExprError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let column = i + 1;
        if c.is_whitespace() {
            i += 1;
            continue;
        }
        let single = match c {
            '+' => Some(Tok::Plus),
            '-' => Some(Tok::Minus),
            '*' => Some(Tok::Star),
            '/' => Some(Tok::Slash),
            '^' => Some(Tok::Caret),
            '(' => Some(Tok::LParen),
            ')' => Some(Tok::RParen),
            _ => None,
        };
        if let Some(t) = single {
            out.push((t, column));
            i += 1;
        } else if c.is_ascii_digit() || c == '.' {
            let start = i;
            let mut mantissa_digits = 0;
            while i < chars.len() && chars[i].is_ascii_digit() {
                i += 1;
                mantissa_digits += 1;
            }
            if i < chars.len() && chars[i] == '.' {
                i += 1;
                while i < chars.len() && chars[i].is_ascii_digit() {
                    i += 1;
                    mantissa_digits += 1;
                }
            }
            // an exponent only when e|E is followed by digits (optionally signed)
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                let mut j = i + 1;
                if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
                    j += 1;
                }
                if j < chars.len() && chars[j].is_ascii_digit() {
                    while j < chars.len() && chars[j].is_ascii_digit() {
                        j += 1;
                    }
                    i = j;
                }
            }
            let s: String = chars[start..i].iter().collect();
            if mantissa_digits == 0 {
                return Err(ExprError::BadNumber { column, text: s, reason: "no digits" });
            }
            let v: f64 = s.parse().map_err(|_| ExprError::BadNumber {
                column,
                text: s.clone(),
                reason: "not a decimal number",
            })?;
            if !v.is_finite() {
                return Err(ExprError::BadNumber { column, text: s, reason: "out of the range of f64" });
            }
            out.push((Tok::Num(s, v), column));
        } else if is_ident_start(c) {
            let start = i;
            while i < chars.len() && is_ident_continue(chars[i]) {
                i += 1;
            }
            out.push((Tok::Ident(chars[start..i].iter().collect()), column));
        } else {
            return Err(ExprError::BadChar { column, found: c });
        }
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------
// Parser

struct Parser {
    toks: Vec<Spanned>,
    pos: usize,
    /// Column one past the end of the text.
    end_column: usize,
    names: Vec<String>,
}

impl Parser {
    fn peek(&self) -> Option<&Tok> {
        self.toks.get(self.pos).map(|(t, _)| t)
    }

    fn column(&self) -> usize {
        self.toks.get(self.pos).map_or(self.end_column, |(_, c)| *c)
    }

    fn found(&self) -> String {
        self.peek().map_or_else(|| "the end".to_string(), Tok::describe)
    }

    fn expected(&self, expected: &'static str) -> ExprError {
        ExprError::Expected { column: self.column(), expected, found: self.found() }
    }

    fn expr(&mut self, depth: usize) -> Result<Node, ExprError> {
        let first = self.term(depth)?;
        let mut terms = vec![(false, first)];
        loop {
            let minus = match self.peek() {
                Some(Tok::Plus) => false,
                Some(Tok::Minus) => true,
                _ => break,
            };
            self.pos += 1;
            terms.push((minus, self.term(depth)?));
        }
        Ok(if terms.len() == 1 { terms.pop().map_or(Node::Num(f64::NAN), |(_, n)| n) } else { Node::Sum(terms) })
    }

    fn term(&mut self, depth: usize) -> Result<Node, ExprError> {
        let first = self.unary(depth)?;
        let mut factors = vec![(false, first)];
        loop {
            let divide = match self.peek() {
                Some(Tok::Star) => false,
                Some(Tok::Slash) => true,
                _ => break,
            };
            self.pos += 1;
            factors.push((divide, self.unary(depth)?));
        }
        Ok(if factors.len() == 1 {
            factors.pop().map_or(Node::Num(f64::NAN), |(_, n)| n)
        } else {
            Node::Product(factors)
        })
    }

    /// Signs are read in a loop (no recursion), each counting one nesting level.
    fn unary(&mut self, depth: usize) -> Result<Node, ExprError> {
        let mut depth = depth;
        let mut negate = false;
        loop {
            match self.peek() {
                Some(Tok::Minus) => negate = !negate,
                Some(Tok::Plus) => {}
                _ => break,
            }
            depth += 1;
            if depth > MAX_NESTING {
                return Err(ExprError::TooDeep { column: self.column(), max: MAX_NESTING });
            }
            self.pos += 1;
        }
        let p = self.power(depth)?;
        Ok(if negate { Node::Neg(Box::new(p)) } else { p })
    }

    fn power(&mut self, depth: usize) -> Result<Node, ExprError> {
        let base = self.atom(depth)?;
        if self.peek() != Some(&Tok::Caret) {
            return Ok(base);
        }
        // exponent chain k₁ ^ k₂ ^ … ^ k_m, folded from the right
        let column = self.toks.get(self.pos + 1).map_or(self.end_column, |(_, c)| *c);
        let mut chain: Vec<u64> = Vec::new();
        while self.peek() == Some(&Tok::Caret) {
            self.pos += 1;
            match self.peek() {
                Some(Tok::Num(s, _)) if s.chars().all(|c| c.is_ascii_digit()) => {
                    // saturating: anything above MAX_EXPONENT is refused below, unless a
                    // later exponent of 0 makes it irrelevant (k^0 = 1)
                    let k = s.parse::<u64>().unwrap_or(u64::MAX);
                    chain.push(k);
                    self.pos += 1;
                }
                _ => return Err(self.expected("a non-negative integer exponent")),
            }
        }
        // right fold e = k₁^(k₂^(…^k_m)), saturating at u64::MAX: an intermediate value
        // above the limit can still be brought back (k^0 = 1, 0^e = 0, 1^e = 1), so only
        // the final value is checked
        let mut e: u64 = chain.pop().unwrap_or(1);
        while let Some(k) = chain.pop() {
            e = if e == 0 {
                1
            } else if k <= 1 {
                k
            } else {
                u32::try_from(e).ok().and_then(|e| k.checked_pow(e)).unwrap_or(u64::MAX)
            };
        }
        let e = u32::try_from(e)
            .ok()
            .filter(|&e| e <= MAX_EXPONENT)
            .ok_or(ExprError::ExponentTooLarge { column, max: MAX_EXPONENT })?;
        Ok(Node::Pow(Box::new(base), e))
    }

    fn atom(&mut self, depth: usize) -> Result<Node, ExprError> {
        let column = self.column();
        match self.peek().cloned() {
            Some(Tok::Num(_, v)) => {
                self.pos += 1;
                Ok(Node::Num(v))
            }
            Some(Tok::Ident(name)) => {
                self.pos += 1;
                let idx = match self.names.iter().position(|n| *n == name) {
                    Some(i) => i,
                    None => {
                        self.names.push(name);
                        self.names.len() - 1
                    }
                };
                Ok(Node::Var(idx))
            }
            Some(Tok::LParen) => {
                let depth = depth + 1;
                if depth > MAX_NESTING {
                    return Err(ExprError::TooDeep { column, max: MAX_NESTING });
                }
                self.pos += 1;
                let inner = self.expr(depth)?;
                if self.peek() != Some(&Tok::RParen) {
                    return Err(self.expected("')' or an operator"));
                }
                self.pos += 1;
                Ok(inner)
            }
            _ => Err(self.expected("a number, an identifier or '('")),
        }
    }
}

// ---------------------------------------------------------------------------------
// Tree evaluation and degree

fn eval_node(node: &Node, vals: &[Option<f64>]) -> Option<f64> {
    Some(match node {
        Node::Num(v) => *v,
        Node::Var(i) => vals.get(*i).copied().flatten()?,
        Node::Neg(a) => -eval_node(a, vals)?,
        Node::Sum(terms) => {
            let mut acc = 0.0;
            for (i, (minus, t)) in terms.iter().enumerate() {
                let v = eval_node(t, vals)?;
                acc = if i == 0 {
                    v
                } else if *minus {
                    acc - v
                } else {
                    acc + v
                };
            }
            acc
        }
        Node::Product(factors) => {
            let mut acc = 0.0;
            for (i, (divide, f)) in factors.iter().enumerate() {
                let v = eval_node(f, vals)?;
                acc = if i == 0 {
                    v
                } else if *divide {
                    acc / v
                } else {
                    acc * v
                };
            }
            acc
        }
        Node::Pow(a, k) => pow_u(eval_node(a, vals)?, *k),
    })
}

/// Degree of `node` in variable `var` (None when it occurs in a denominator), or the
/// degree 0 when `var` is `None` (not in the text).
fn degree_node(node: &Node, var: usize) -> Option<u32> {
    match node {
        Node::Num(_) => Some(0),
        Node::Var(i) => Some(u32::from(*i == var)),
        Node::Neg(a) => degree_node(a, var),
        Node::Sum(terms) => {
            let mut d = 0;
            for (_, t) in terms {
                d = d.max(degree_node(t, var)?);
            }
            Some(d)
        }
        Node::Product(factors) => {
            let mut d: u32 = 0;
            for (divide, f) in factors {
                let df = degree_node(f, var)?;
                if *divide {
                    if df > 0 {
                        return None;
                    }
                } else {
                    d = d.saturating_add(df);
                }
            }
            Some(d)
        }
        Node::Pow(a, k) => Some(degree_node(a, var)?.saturating_mul(*k)),
    }
}

impl Expr {
    /// Parses polynomial text (grammar in the module documentation).
    pub fn parse(text: &str) -> Result<Expr, ExprError> {
        if text.len() > MAX_TEXT_LEN {
            return Err(ExprError::TooLong { len: text.len(), max: MAX_TEXT_LEN });
        }
        let toks = lex(text)?;
        let mut p = Parser { toks, pos: 0, end_column: text.chars().count() + 1, names: Vec::new() };
        let root = p.expr(0)?;
        if p.pos < p.toks.len() {
            return Err(p.expected("an operator or the end"));
        }
        Ok(Expr { root, names: p.names })
    }

    /// The distinct identifiers of the text, in order of first appearance.
    pub fn identifiers(&self) -> &[String] {
        &self.names
    }

    /// Whether `name` occurs in the text.
    pub fn mentions(&self, name: &str) -> bool {
        self.names.iter().any(|n| n == name)
    }

    /// Evaluates the tree, looking identifiers up with `lookup`; `None` when an
    /// identifier is unknown to it. Slow (one look-up per identifier per call): for
    /// repeated evaluation use [`Expr::bind`].
    pub fn eval(&self, lookup: &dyn Fn(&str) -> Option<f64>) -> Option<f64> {
        let vals: Vec<Option<f64>> = self.names.iter().map(|n| lookup(n)).collect();
        eval_node(&self.root, &vals)
    }

    /// The largest degree of the text in `name`, read from its structure (an upper bound
    /// on the degree of the expanded polynomial: `w - w` has degree 1 here). 0 when the
    /// text does not mention `name`; `None` when `name` occurs in a denominator.
    pub fn degree_in(&self, name: &str) -> Option<u32> {
        match self.names.iter().position(|n| n == name) {
            Some(var) => degree_node(&self.root, var),
            None => Some(0),
        }
    }

    /// Compiles the text against the variable list `names`: `Bound::eval(v)` then reads
    /// identifier `names[i]` as `v[i]`. Every identifier of the text must be in `names`
    /// (the first occurrence counts when a name is listed twice); names the text does
    /// not use are allowed.
    pub fn bind<S: AsRef<str>>(&self, names: &[S]) -> Result<Bound, ExprError> {
        let mut map = Vec::with_capacity(self.names.len());
        for n in &self.names {
            match names.iter().position(|m| m.as_ref() == n) {
                Some(i) => map.push(i),
                None => return Err(ExprError::UnknownIdentifier { name: n.clone() }),
            }
        }
        let code = match compile(&self.root, &map) {
            Item::Const(c) => vec![Op::Const(c)],
            Item::Var(i) => vec![Op::Var(i)],
            Item::Code(code) => code,
        };
        let max_stack = stack_need(&code);
        Ok(Bound { code, n_vars: names.len(), max_stack })
    }
}

// ---------------------------------------------------------------------------------
// Compilation to a stack program

/// One instruction. `…C`/`…V` forms take their right operand from the instruction (a
/// constant, or a variable) instead of the stack.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Op {
    Const(f64),
    Var(usize),
    /// push v[i]^k
    VarPow(usize, u32),
    Add,
    Sub,
    Mul,
    Div,
    AddC(f64),
    SubC(f64),
    MulC(f64),
    DivC(f64),
    AddV(usize),
    SubV(usize),
    MulV(usize),
    DivV(usize),
    Neg,
    Pow(u32),
}

/// A compiled subtree: a folded constant, a lone variable (not yet pushed), or code
/// that leaves its value on top of the stack.
enum Item {
    Const(f64),
    Var(usize),
    Code(Vec<Op>),
}

impl Item {
    fn push_into(self, code: &mut Vec<Op>) {
        match self {
            Item::Const(c) => code.push(Op::Const(c)),
            Item::Var(i) => code.push(Op::Var(i)),
            Item::Code(c) => code.extend(c),
        }
    }
}

/// Folds `a op b` for a left-to-right list (sums: op = ±, products: op = ×/÷), with the
/// same `f64` operations in the same order as `eval_node`.
fn compile_list(items: &[(bool, Node)], map: &[usize], is_sum: bool) -> Item {
    let apply = |a: f64, inv: bool, b: f64| match (is_sum, inv) {
        (true, false) => a + b,
        (true, true) => a - b,
        (false, false) => a * b,
        (false, true) => a / b,
    };
    let mut acc: Option<Item> = None;
    for (inv, node) in items {
        let inv = *inv;
        let it = compile(node, map);
        acc = Some(match acc {
            None => it,
            Some(Item::Const(a)) => match it {
                Item::Const(b) => Item::Const(apply(a, inv, b)),
                // a + X = X + a and a·X = X·a exactly in IEEE arithmetic (not so for − and
                // ÷: a − X and −(X − a) differ in the sign of an exact zero)
                other if !inv => {
                    let mut code = Vec::new();
                    other.push_into(&mut code);
                    code.push(if is_sum { Op::AddC(a) } else { Op::MulC(a) });
                    Item::Code(code)
                }
                other => {
                    let mut code = vec![Op::Const(a)];
                    other.push_into(&mut code);
                    code.push(binary(is_sum, inv));
                    Item::Code(code)
                }
            },
            Some(left) => {
                let mut code = Vec::new();
                left.push_into(&mut code);
                match it {
                    Item::Const(b) => code.push(match (is_sum, inv) {
                        (true, false) => Op::AddC(b),
                        (true, true) => Op::SubC(b),
                        (false, false) => Op::MulC(b),
                        (false, true) => Op::DivC(b),
                    }),
                    Item::Var(i) => code.push(match (is_sum, inv) {
                        (true, false) => Op::AddV(i),
                        (true, true) => Op::SubV(i),
                        (false, false) => Op::MulV(i),
                        (false, true) => Op::DivV(i),
                    }),
                    Item::Code(c) => {
                        code.extend(c);
                        code.push(binary(is_sum, inv));
                    }
                }
                Item::Code(code)
            }
        });
    }
    acc.unwrap_or(Item::Const(f64::NAN))
}

fn binary(is_sum: bool, inv: bool) -> Op {
    match (is_sum, inv) {
        (true, false) => Op::Add,
        (true, true) => Op::Sub,
        (false, false) => Op::Mul,
        (false, true) => Op::Div,
    }
}

fn compile(node: &Node, map: &[usize]) -> Item {
    match node {
        Node::Num(v) => Item::Const(*v),
        Node::Var(i) => Item::Var(map.get(*i).copied().unwrap_or(usize::MAX)),
        Node::Neg(a) => match compile(a, map) {
            Item::Const(c) => Item::Const(-c),
            other => {
                let mut code = Vec::new();
                other.push_into(&mut code);
                code.push(Op::Neg);
                Item::Code(code)
            }
        },
        Node::Sum(terms) => compile_list(terms, map, true),
        Node::Product(factors) => compile_list(factors, map, false),
        Node::Pow(a, k) => match compile(a, map) {
            Item::Const(c) => Item::Const(pow_u(c, *k)),
            Item::Var(i) => Item::Code(vec![Op::VarPow(i, *k)]),
            Item::Code(mut code) => {
                code.push(Op::Pow(*k));
                Item::Code(code)
            }
        },
    }
}

/// The deepest stack a program reaches.
fn stack_need(code: &[Op]) -> usize {
    let mut depth: usize = 0;
    let mut max = 0;
    for op in code {
        match op {
            Op::Const(_) | Op::Var(_) | Op::VarPow(..) => {
                depth += 1;
                max = max.max(depth);
            }
            Op::Add | Op::Sub | Op::Mul | Op::Div => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    max
}

/// A compiled expression ([`Expr::bind`]): a flat stack program.
#[derive(Clone, Debug, PartialEq)]
pub struct Bound {
    code: Vec<Op>,
    n_vars: usize,
    max_stack: usize,
}

impl Bound {
    /// Number of variables (the length of the `names` it was bound with).
    pub fn n_vars(&self) -> usize {
        self.n_vars
    }

    /// Number of instructions (constants folded, leaf operands fused).
    pub fn len(&self) -> usize {
        self.code.len()
    }

    /// Whether the program is empty (never: a constant is one instruction).
    pub fn is_empty(&self) -> bool {
        self.code.is_empty()
    }

    /// Stack slots the program needs (see [`Bound::eval_with`]).
    pub fn stack_need(&self) -> usize {
        self.max_stack
    }

    /// The value at `vars` (`vars[i]` is the variable `names[i]` of [`Expr::bind`]).
    /// NaN when `vars` is shorter than the names. No allocation when the program needs
    /// at most [`INLINE_STACK`] slots.
    pub fn eval(&self, vars: &[f64]) -> f64 {
        if self.max_stack <= INLINE_STACK {
            let mut stack = [0.0; INLINE_STACK];
            self.run(vars, &mut stack)
        } else {
            let mut stack = vec![0.0; self.max_stack];
            self.run(vars, &mut stack)
        }
    }

    /// [`Bound::eval`] with a caller's stack buffer (grown when shorter than
    /// [`Bound::stack_need`]): no allocation whatever the program.
    pub fn eval_with(&self, vars: &[f64], stack: &mut Vec<f64>) -> f64 {
        if stack.len() < self.max_stack {
            stack.resize(self.max_stack, 0.0);
        }
        self.run(vars, stack)
    }

    /// The stack machine, with the top of the stack kept in a local (`acc`, a register)
    /// and the values below it in `st`: the fused `…C`/`…V` instructions, most of a
    /// program, touch no memory. A push spills `acc` to `st` (the first spill stores a
    /// placeholder), so `st` needs [`Bound::stack_need`] slots.
    fn run(&self, vars: &[f64], st: &mut [f64]) -> f64 {
        if vars.len() < self.n_vars || st.len() < self.max_stack {
            return f64::NAN;
        }
        // Every variable index is < n_vars ≤ vars.len() and the program is well formed
        // (built by `compile`: a binary operation always finds a value below the top, and
        // the depth stays within `max_stack`), so the indexing below cannot fail.
        let mut acc = f64::NAN;
        let mut sp = 0usize;
        for op in &self.code {
            match *op {
                Op::Const(c) => {
                    st[sp] = acc;
                    sp += 1;
                    acc = c;
                }
                Op::Var(i) => {
                    st[sp] = acc;
                    sp += 1;
                    acc = vars[i];
                }
                Op::VarPow(i, k) => {
                    st[sp] = acc;
                    sp += 1;
                    acc = pow_u(vars[i], k);
                }
                Op::Add => {
                    sp -= 1;
                    acc += st[sp]; // IEEE addition commutes bit for bit
                }
                Op::Sub => {
                    sp -= 1;
                    acc = st[sp] - acc;
                }
                Op::Mul => {
                    sp -= 1;
                    acc *= st[sp];
                }
                Op::Div => {
                    sp -= 1;
                    acc = st[sp] / acc;
                }
                Op::AddC(c) => acc += c,
                Op::SubC(c) => acc -= c,
                Op::MulC(c) => acc *= c,
                Op::DivC(c) => acc /= c,
                Op::AddV(i) => acc += vars[i],
                Op::SubV(i) => acc -= vars[i],
                Op::MulV(i) => acc *= vars[i],
                Op::DivV(i) => acc /= vars[i],
                Op::Neg => acc = -acc,
                Op::Pow(k) => acc = pow_u(acc, k),
            }
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The value of `text` with x = 3, y = 2, w = 0.5 (tree and compiled, which must agree
    /// bit for bit).
    fn val(text: &str) -> f64 {
        let e = Expr::parse(text).unwrap_or_else(|err| panic!("{text}: {err}"));
        let names = ["x", "y", "w"];
        let vals = [3.0, 2.0, 0.5];
        let tree = e
            .eval(&|n: &str| names.iter().position(|m| *m == n).map(|i| vals[i]))
            .unwrap_or_else(|| panic!("{text}: unknown identifier"));
        let compiled = e.bind(&names).unwrap().eval(&vals);
        assert_eq!(tree.to_bits(), compiled.to_bits(), "{text}: tree {tree} vs compiled {compiled}");
        tree
    }

    #[test]
    fn precedence_and_associativity() {
        assert_eq!(val("1 + 2*3"), 7.0);
        assert_eq!(val("2*3^2"), 18.0);
        assert_eq!(val("-x^2"), -9.0);
        assert_eq!(val("(-x)^2"), 9.0);
        assert_eq!(val("-x^2 + y"), -7.0);
        assert_eq!(val("2 - -x"), 5.0);
        assert_eq!(val("10 - x - y"), 5.0);
        assert_eq!(val("24 / x / y"), 4.0);
        assert_eq!(val("8 / y * y"), 8.0);
        assert_eq!(val("x - (y - 1)"), 2.0);
        assert_eq!(val("--x"), 3.0);
        assert_eq!(val("-+-x"), 3.0);
        assert_eq!(val("+x"), 3.0);
        assert_eq!(val("2^3^2"), 512.0); // right-associative: 2^(3^2)
        assert_eq!(val("y^2^3"), 256.0); // y^8
        assert_eq!(val("x^5^0"), 3.0); // x^(5^0) = x^1
        assert_eq!(val("x^0"), 1.0);
        assert_eq!(val("0^0"), 1.0);
        assert_eq!(val("x^1^100"), 3.0); // x^(1^100)
        assert_eq!(val("(x^2)^3"), 729.0);
        assert_eq!(val("x*y^2*w"), 6.0);
        assert_eq!(val("x/(y - 2)"), f64::INFINITY); // plain f64 division
        assert_eq!(val("w^2 - (x - (y + 0.5*w))^2"), 0.25 - 0.5625);
        assert_eq!(val(" 1e41 "), 1e41);
        assert_eq!(val("1.5e-3"), 1.5e-3);
        assert_eq!(val(".5 + 5."), 5.5);
        assert_eq!(val("1E+2 - 2e0"), 98.0);
        assert_eq!(val("(x/1e21)^8"), pow_u(3.0 / 1e21, 8));
        assert_eq!(val("7.16e-324*x"), 7.16e-324 * 3.0);
        assert_eq!(val("0.3^2"), 0.3 * 0.3);
    }

    #[test]
    fn parse_errors_are_typed_with_columns() {
        let err = |t: &str| Expr::parse(t).unwrap_err();
        assert!(matches!(err(""), ExprError::Expected { column: 1, .. }));
        assert!(matches!(err("1 +"), ExprError::Expected { column: 4, .. }));
        assert!(matches!(err("2x1"), ExprError::Expected { column: 2, .. }));
        assert!(matches!(err("2 x1"), ExprError::Expected { column: 3, .. }));
        assert!(matches!(err("x^-1"), ExprError::Expected { column: 3, .. }));
        assert!(matches!(err("x^2.0"), ExprError::Expected { .. }));
        assert!(matches!(err("x^1e1"), ExprError::Expected { .. }));
        assert!(matches!(err("x^y"), ExprError::Expected { .. }));
        assert!(matches!(err("(x"), ExprError::Expected { column: 3, .. }));
        assert!(matches!(err("x)"), ExprError::Expected { column: 2, .. }));
        assert!(matches!(err("()"), ExprError::Expected { column: 2, .. }));
        assert!(matches!(err("x # y"), ExprError::BadChar { column: 3, found: '#' }));
        assert!(matches!(err("x, y"), ExprError::BadChar { .. }));
        assert!(matches!(err("1e400"), ExprError::BadNumber { .. }));
        assert!(matches!(err("."), ExprError::BadNumber { .. }));
        assert!(matches!(err("x ** 2"), ExprError::Expected { .. }));
        assert!(matches!(err("x^65"), ExprError::ExponentTooLarge { column: 3, max: 64 }));
        assert!(matches!(err("x^2^7"), ExprError::ExponentTooLarge { .. }));
        assert!(matches!(err("x^99999999999999999999999999"), ExprError::ExponentTooLarge { .. }));
        assert!(matches!(err("x^2^99999999999999999999"), ExprError::ExponentTooLarge { .. }));
        assert!(Expr::parse("x^64").is_ok());
        assert!(Expr::parse("x^99999999999999999999^0").is_ok()); // x^1
                                                                  // the message names the column and what was expected
        assert_eq!(err("1 + * 2").to_string(), "column 5: expected a number, an identifier or '(', found '*'");
    }

    #[test]
    fn size_and_nesting_limits() {
        let deep = |k: usize| format!("{}x{}", "(".repeat(k), ")".repeat(k));
        assert!(Expr::parse(&deep(MAX_NESTING)).is_ok());
        assert!(matches!(Expr::parse(&deep(MAX_NESTING + 1)), Err(ExprError::TooDeep { .. })));
        let signs = |k: usize| format!("{}x", "-".repeat(k));
        assert_eq!(val(&signs(MAX_NESTING)), 3.0);
        assert!(matches!(Expr::parse(&signs(MAX_NESTING + 1)), Err(ExprError::TooDeep { .. })));
        // signs and parentheses add up
        assert!(Expr::parse(&format!("{}({})", "-".repeat(100), signs(100))).is_err());
        let long = format!("{}1", "x + ".repeat(MAX_TEXT_LEN / 4));
        assert!(matches!(Expr::parse(&long), Err(ExprError::TooLong { .. })));
        // a long flat sum and product: no deep recursion (the tree is flat)
        let sum = format!("{}x", "x - ".repeat(MAX_TEXT_LEN / 4 - 1));
        assert_eq!(val(&sum), 3.0 - 3.0 * (MAX_TEXT_LEN / 4 - 1) as f64);
        let product = format!("{}1", "w*".repeat(MAX_TEXT_LEN / 2 - 1));
        assert_eq!(val(&product), 0.0); // 0.5^49999 underflows
                                        // a program deeper than the inline stack: x*(x+(x*(x+…)))
        let mut t = "x".to_string();
        for i in 0..60 {
            t = if i % 2 == 0 { format!("w*(y+{t})") } else { format!("0.5+(w*{t})") };
        }
        let e = Expr::parse(&t).unwrap();
        let b = e.bind(&["x", "y", "w"]).unwrap();
        assert!(b.stack_need() > INLINE_STACK);
        let v = val(&t);
        let mut stack = Vec::new();
        assert_eq!(b.eval_with(&[3.0, 2.0, 0.5], &mut stack).to_bits(), v.to_bits());
    }

    #[test]
    fn degree_identifiers_and_binding() {
        let e = Expr::parse("w^2 - (x1 - w)^3*w + t").unwrap();
        assert_eq!(e.degree_in("w"), Some(4));
        assert_eq!(e.degree_in("x1"), Some(3));
        assert_eq!(e.degree_in("t"), Some(1));
        assert_eq!(e.degree_in("v"), Some(0));
        assert_eq!(e.identifiers(), ["w", "x1", "t"]);
        assert!(e.mentions("x1") && !e.mentions("x"));
        assert_eq!(Expr::parse("x1/w").unwrap().degree_in("w"), None);
        assert_eq!(Expr::parse("x1/w").unwrap().degree_in("x1"), Some(1));
        assert_eq!(Expr::parse("w/(1 + x1)").unwrap().degree_in("w"), Some(1));
        assert_eq!(Expr::parse("w/(1 + x1)").unwrap().degree_in("x1"), None);
        assert_eq!(Expr::parse("(w^2)^3 / 4").unwrap().degree_in("w"), Some(6));
        assert_eq!(Expr::parse("w - w").unwrap().degree_in("w"), Some(1)); // structural
        assert_eq!(Expr::parse("ω1^2 + _a").unwrap().identifiers(), ["ω1", "_a"]);
        // binding
        assert_eq!(e.bind(&["t", "x1"]).unwrap_err(), ExprError::UnknownIdentifier { name: "w".into() });
        let b = e.bind(&["x1", "t", "w", "unused"]).unwrap();
        assert_eq!(b.n_vars(), 4);
        assert_eq!(b.eval(&[1.0, 10.0, 2.0, f64::NAN]), 4.0 - (1.0f64 - 2.0).powi(3) * 2.0 + 10.0);
        assert!(b.eval(&[1.0, 2.0]).is_nan()); // too few values: NaN, no panic
                                               // constants fold: one instruction
        assert_eq!(Expr::parse("0.3^2 - 2*(1 + 1)").unwrap().bind::<&str>(&[]).unwrap().len(), 1);
    }

    /// Compiled and tree evaluation agree bit for bit on random points for the kinds of
    /// text the scenes hold.
    #[test]
    fn compiled_matches_tree_everywhere() {
        let texts = [
            "-0.42*x1^5 - 1.18*x1^4*x2 - 0.47*x1^4 + 0.3*x1^3*x2^2 - 0.57*x1^3*x2 + 0.6*x1^3 - 0.65*x1^2*x2^3 \
             + 0.17*x1^2*x2^2 + 1.87*x1^2*x2 + 0.06*x1^2 + 0.69*x1*x2^4 - 0.14*x1*x2^3 - 0.85*x1*x2^2 + 0.6*x1*x2 \
             - 0.21*x1 + 0.01*x2^5 - 0.06*x2^4 - 0.07*x2^3 - 0.41*x2^2 - 0.08*x2 + 0.07 - 0.1*w",
            "w^2 - (x1 - (t-1e18)/256 + 2)^2 - x2^2",
            "0.3^2 - (x1 - (t + 0.4 + w))^2 - (x2 - 1)^2",
            "w - (x1/1e21)^8 - (x2/1e21)^8",
            "-(x1 - w*t)/(-4) * (x2 + 1)^3 - -t",
        ];
        let names = ["x1", "x2", "t", "w"];
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for text in texts {
            let e = Expr::parse(text).unwrap();
            let b = e.bind(&names).unwrap();
            for _ in 0..1000 {
                let v: Vec<f64> = (0..4).map(|_| rng.random_range(-3.0..3.0)).collect();
                let tree = e.eval(&|n: &str| names.iter().position(|m| *m == n).map(|i| v[i])).unwrap();
                assert_eq!(tree.to_bits(), b.eval(&v).to_bits(), "{text} at {v:?}");
            }
        }
    }

    /// Random text over the grammar's alphabet: never a panic, and whatever parses binds
    /// and evaluates.
    #[test]
    fn random_text_never_panics() {
        let alphabet: Vec<char> = "x1wt0.5e+-*/^() 9E_#ωa".chars().collect();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut parsed = 0;
        for _ in 0..20_000 {
            let len = rng.random_range(0..24);
            let s: String = (0..len).map(|_| alphabet[rng.random_range(0..alphabet.len())]).collect();
            if let Ok(e) = Expr::parse(&s) {
                parsed += 1;
                let names: Vec<String> = e.identifiers().to_vec();
                let b = e.bind(&names).unwrap();
                let _ = b.eval(&vec![0.7; names.len()]);
                for n in &names {
                    let _ = e.degree_in(n);
                }
            }
        }
        assert!(parsed > 100, "{parsed}");
    }

    /// Evaluation speed of a compiled scene polynomial (printed, not asserted: it depends
    /// on the machine and its load).
    #[test]
    fn compiled_evaluation_speed() {
        let e = Expr::parse(
            "r1^2 - (x1 - (0.2 + 0.3*t + u1))^2 - (x2 - (0.2 + 0.3*t + v1))^2 - (x3 - (0.2 + 0.3*t + w1))^2",
        )
        .unwrap();
        let b = e.bind(&["x1", "x2", "x3", "t", "r1", "u1", "v1", "w1"]).unwrap();
        let mut v = [0.1, 0.2, 0.3, 0.5, 0.15, 0.0, 0.01, -0.02];
        let n = 2_000_000;
        let start = std::time::Instant::now();
        let mut acc = 0.0;
        for i in 0..n {
            v[5] = (i % 100) as f64 * 1e-3;
            acc += b.eval(&v);
        }
        let dt = start.elapsed().as_secs_f64();
        eprintln!("{} instructions, {:.1} ns per evaluation (checksum {acc:.3})", b.len(), dt / n as f64 * 1e9);
        assert!(acc.is_finite());
    }
}
