//! `[bind]` expressions: `+ - * / ^ ( )`, `sqrt(…)`, decimal numbers and declared symbols, in f64.
//!
//! Grammar (usual mathematical conventions, as in Python or Julia):
//!
//! ```text
//! sum     := product (('+' | '-') product)*
//! product := unary (('*' | '/') unary)*
//! unary   := ('-' | '+') unary | power
//! power   := primary ('^' unary)?          right-associative: 2^3^2 = 2^9; -2^2 = -(2^2) = -4
//! primary := number | symbol | 'sqrt' '(' sum ')' | '(' sum ')'
//! number  := digits ['.' digits] [('e' | 'E') ['+' | '-'] digits]   (also '.5' and '5.')
//! ```
//!
//! All arithmetic is f64 (`1/12` is 0.0833…, never integer division). An expression is parsed once
//! into a small tree; evaluating it walks the tree and allocates nothing. Out-of-domain operations
//! follow IEEE (`sqrt(-1)` is NaN, `1/0` is ∞): the caller validates the values it writes.
//!
//! Depth is limited ([`Expression::MAX_DEPTH`]): the parser's nesting (parentheses, signs, `sqrt`, exponents)
//! and the height of the tree (a chain of n binary operators is n deep) are both refused beyond it
//! with [`ExpressionError::TooDeep`], so that neither parsing, evaluating nor dropping a hostile
//! expression (100 000 nested parentheses) can overflow the stack.
//!
//! Why not a crate: evalexpr divides integers and names the root `math::sqrt`; exmex (0.21) gives
//! unary minus precedence over `^` (`-2^2 = 4`, so `-l1^2` would silently be `+l1²`), evaluates `^`
//! left to right (`2^3^2 = 64`), does not read `1e-3` without a custom literal matcher, and accepts
//! functions and constants (`sin`, `E`, `π`) the sidecar contract does not have.

use thiserror::Error;

/// Why an expression text was refused. Columns count characters from 1.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum ExpressionError {
    /// Nothing but white space.
    #[error("the expression is empty")]
    Empty,
    /// A character that no token starts with.
    #[error("unexpected character '{character}' at column {column}; expressions use numbers, symbols, + - * / ^ ( ) and sqrt(…)")]
    UnexpectedCharacter {
        /// Column of the character.
        column: usize,
        /// The character.
        character: char,
    },
    /// A malformed number such as `1.2.3` or `1e`.
    #[error("'{text}' at column {column} is not a number")]
    BadNumber {
        /// Column where the number starts.
        column: usize,
        /// The text read as a number.
        text: String,
    },
    /// A token where another was expected.
    #[error("expected {expected} at column {column}, found {found}")]
    Expected {
        /// Column of the offending token.
        column: usize,
        /// What the grammar allows there.
        expected: &'static str,
        /// The token found, or "the end of the expression".
        found: String,
    },
    /// A function call other than `sqrt`.
    #[error("unknown function '{name}' at column {column}; the only function is sqrt(…)")]
    UnknownFunction {
        /// Column of the name.
        column: usize,
        /// The name.
        name: String,
    },
    /// A name that is not among the declared symbols.
    #[error("unknown symbol '{name}' at column {column}")]
    UnknownSymbol {
        /// Column of the name.
        column: usize,
        /// The name.
        name: String,
    },
    /// Nested deeper than [`Expression::MAX_DEPTH`] levels.
    #[error("the expression nests deeper than {limit} levels at column {column} (each parenthesis, sign, sqrt, ^ and each operator of a chain adds one); simplify it or split it with a free symbol")]
    TooDeep {
        /// Column of the token where the limit was passed.
        column: usize,
        /// The limit, [`Expression::MAX_DEPTH`].
        limit: usize,
    },
}

/// Deepest nesting and tree height an expression may have. Real `[bind]` expressions are a few
/// levels deep (`l1 * l1 / 12` is 2); 256 leaves room for generated ones while keeping the
/// recursion of parsing (about five stack frames per level) and evaluation far below the 2 MiB
/// stack of a test or worker thread.
pub const MAX_DEPTH: usize = 256;

/// The name of the one function expressions may call; it cannot be a symbol.
pub const SQRT: &str = "sqrt";

/// A parsed expression over numbered symbols.
#[derive(Clone, Debug, PartialEq)]
pub struct Expression {
    source: String,
    root: Node,
    symbols: Vec<usize>,
}

#[derive(Clone, Debug, PartialEq)]
enum Node {
    Number(f64),
    Symbol(usize),
    Negate(Box<Node>),
    Sqrt(Box<Node>),
    Binary(BinaryOp, Box<Node>, Box<Node>),
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum BinaryOp {
    Add,
    Subtract,
    Multiply,
    Divide,
    Power,
}

impl Expression {
    /// Deepest nesting and tree height an expression may have (see [`ExpressionError::TooDeep`]):
    /// 256, which keeps parsing and evaluation far from the end of any thread's stack.
    pub const MAX_DEPTH: usize = MAX_DEPTH;

    /// Parses `text`; a name `symbols[k]` becomes symbol number `k` (names that cannot be
    /// identifiers, such as dotted paths, simply never match).
    pub fn parse(text: &str, symbols: &[&str]) -> Result<Expression, ExpressionError> {
        let tokens = tokenize(text)?;
        if tokens.is_empty() {
            return Err(ExpressionError::Empty);
        }
        let mut parser = Parser {
            tokens: &tokens,
            position: 0,
            end_column: text.chars().count() + 1,
            symbols,
            used: Vec::new(),
            nesting: 0,
        };
        let (root, _) = parser.sum()?;
        if let Some(token) = parser.peek() {
            return Err(ExpressionError::Expected {
                column: token.column,
                expected: "an operator or the end of the expression",
                found: token.kind.describe(),
            });
        }
        let mut used = parser.used;
        used.sort_unstable();
        used.dedup();
        Ok(Expression {
            source: text.to_string(),
            root,
            symbols: used,
        })
    }

    /// The text the expression was parsed from.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The symbol numbers the expression uses, ascending, each once.
    pub fn symbols(&self) -> &[usize] {
        &self.symbols
    }

    /// The value with symbol `k` worth `value_of(k)`. Allocates nothing.
    #[inline]
    pub fn eval<F: Fn(usize) -> f64>(&self, value_of: &F) -> f64 {
        self.root.eval(value_of)
    }

    /// The value with symbol `k` worth `values[k]` (`values` must cover every symbol used).
    pub fn eval_with(&self, values: &[f64]) -> f64 {
        self.eval(&|k| values[k])
    }
}

impl std::fmt::Display for Expression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.source)
    }
}

impl Node {
    fn eval<F: Fn(usize) -> f64>(&self, value_of: &F) -> f64 {
        match self {
            Node::Number(value) => *value,
            Node::Symbol(k) => value_of(*k),
            Node::Negate(inner) => -inner.eval(value_of),
            Node::Sqrt(inner) => inner.eval(value_of).sqrt(),
            Node::Binary(op, a, b) => {
                let (a, b) = (a.eval(value_of), b.eval(value_of));
                match op {
                    BinaryOp::Add => a + b,
                    BinaryOp::Subtract => a - b,
                    BinaryOp::Multiply => a * b,
                    BinaryOp::Divide => a / b,
                    BinaryOp::Power => power(a, b),
                }
            }
        }
    }
}

/// `a^b`, with integer exponents done by repeated multiplication (exact squares: `l^2 == l*l`).
fn power(a: f64, b: f64) -> f64 {
    if b == b.trunc() && b.abs() <= 64.0 {
        // In range by the test above.
        a.powi(b as i32)
    } else {
        a.powf(b)
    }
}

#[derive(Clone, Debug, PartialEq)]
enum TokenKind {
    Number(f64),
    Name(String),
    Operator(char),
    Open,
    Close,
}

impl TokenKind {
    fn describe(&self) -> String {
        match self {
            TokenKind::Number(value) => format!("the number {value}"),
            TokenKind::Name(name) => format!("'{name}'"),
            TokenKind::Operator(op) => format!("'{op}'"),
            TokenKind::Open => "'('".to_string(),
            TokenKind::Close => "')'".to_string(),
        }
    }
}

#[derive(Clone, Debug)]
struct Token {
    kind: TokenKind,
    column: usize,
}

fn tokenize(text: &str) -> Result<Vec<Token>, ExpressionError> {
    let chars: Vec<char> = text.chars().collect();
    let mut tokens = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let column = i + 1;
        if c.is_whitespace() {
            i += 1;
            continue;
        }
        let kind = if c.is_ascii_digit() || c == '.' {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                i += 1;
                if i < chars.len() && (chars[i] == '+' || chars[i] == '-') {
                    i += 1;
                }
                while i < chars.len() && chars[i].is_ascii_digit() {
                    i += 1;
                }
            }
            let number: String = chars[start..i].iter().collect();
            match number.parse::<f64>() {
                Ok(value) => TokenKind::Number(value),
                Err(_) => {
                    return Err(ExpressionError::BadNumber {
                        column,
                        text: number,
                    })
                }
            }
        } else if c.is_ascii_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            TokenKind::Name(chars[start..i].iter().collect())
        } else {
            i += 1;
            match c {
                '+' | '-' | '*' | '/' | '^' => TokenKind::Operator(c),
                '(' => TokenKind::Open,
                ')' => TokenKind::Close,
                _ => {
                    return Err(ExpressionError::UnexpectedCharacter {
                        column,
                        character: c,
                    })
                }
            }
        };
        tokens.push(Token { kind, column });
    }
    Ok(tokens)
}

/// Recursive descent over the tokens, one function per grammar rule. Each rule returns its node
/// and the node's height (a leaf is 1), checked against [`MAX_DEPTH`] whenever a node is built.
struct Parser<'a> {
    tokens: &'a [Token],
    position: usize,
    end_column: usize,
    symbols: &'a [&'a str],
    used: Vec<usize>,
    /// Current recursion depth of [`Parser::unary`], through which every nesting passes.
    nesting: usize,
}

/// A parsed node and its height.
type Parsed = (Node, usize);

impl Parser<'_> {
    fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.position)
    }

    fn next_operator_in(&mut self, ops: &[char]) -> Option<char> {
        match self.peek() {
            Some(Token {
                kind: TokenKind::Operator(op),
                ..
            }) if ops.contains(op) => {
                let op = *op;
                self.position += 1;
                Some(op)
            }
            _ => None,
        }
    }

    fn expected(&self, expected: &'static str) -> ExpressionError {
        match self.peek() {
            Some(token) => ExpressionError::Expected {
                column: token.column,
                expected,
                found: token.kind.describe(),
            },
            None => ExpressionError::Expected {
                column: self.end_column,
                expected,
                found: "the end of the expression".to_string(),
            },
        }
    }

    /// The error for passing [`MAX_DEPTH`] at the current token.
    fn too_deep(&self) -> ExpressionError {
        ExpressionError::TooDeep {
            column: self
                .tokens
                .get(self.position.saturating_sub(1))
                .map_or(self.end_column, |t| t.column),
            limit: MAX_DEPTH,
        }
    }

    /// A node over children of heights `heights`, refused when it would pass [`MAX_DEPTH`].
    fn node(&self, node: Node, heights: &[usize]) -> Result<Parsed, ExpressionError> {
        let height = 1 + heights.iter().copied().max().unwrap_or(0);
        if height > MAX_DEPTH {
            return Err(self.too_deep());
        }
        Ok((node, height))
    }

    fn sum(&mut self) -> Result<Parsed, ExpressionError> {
        let mut left = self.product()?;
        while let Some(op) = self.next_operator_in(&['+', '-']) {
            let op = if op == '+' {
                BinaryOp::Add
            } else {
                BinaryOp::Subtract
            };
            let right = self.product()?;
            let heights = [left.1, right.1];
            left = self.node(
                Node::Binary(op, Box::new(left.0), Box::new(right.0)),
                &heights,
            )?;
        }
        Ok(left)
    }

    fn product(&mut self) -> Result<Parsed, ExpressionError> {
        let mut left = self.unary()?;
        while let Some(op) = self.next_operator_in(&['*', '/']) {
            let op = if op == '*' {
                BinaryOp::Multiply
            } else {
                BinaryOp::Divide
            };
            let right = self.unary()?;
            let heights = [left.1, right.1];
            left = self.node(
                Node::Binary(op, Box::new(left.0), Box::new(right.0)),
                &heights,
            )?;
        }
        Ok(left)
    }

    /// Every nesting (parentheses and `sqrt` through `sum`, signs, exponents) passes through here,
    /// so the recursion depth is counted once, here.
    fn unary(&mut self) -> Result<Parsed, ExpressionError> {
        if self.nesting >= MAX_DEPTH {
            return Err(self.too_deep());
        }
        self.nesting += 1;
        let result = match self.next_operator_in(&['-', '+']) {
            Some('-') => self
                .unary()
                .and_then(|(inner, h)| self.node(Node::Negate(Box::new(inner)), &[h])),
            Some(_) => self.unary(),
            None => self.power(),
        };
        self.nesting -= 1;
        result
    }

    fn power(&mut self) -> Result<Parsed, ExpressionError> {
        let base = self.primary()?;
        if self.next_operator_in(&['^']).is_some() {
            let exponent = self.unary()?;
            let heights = [base.1, exponent.1];
            return self.node(
                Node::Binary(BinaryOp::Power, Box::new(base.0), Box::new(exponent.0)),
                &heights,
            );
        }
        Ok(base)
    }

    fn primary(&mut self) -> Result<Parsed, ExpressionError> {
        const OPERAND: &str = "a number, a symbol, sqrt(…) or '('";
        let Some(token) = self.peek().cloned() else {
            return Err(self.expected(OPERAND));
        };
        match token.kind {
            TokenKind::Number(value) => {
                self.position += 1;
                Ok((Node::Number(value), 1))
            }
            TokenKind::Open => {
                self.position += 1;
                let inner = self.sum()?;
                self.close()?;
                Ok(inner)
            }
            TokenKind::Name(name) => {
                self.position += 1;
                let is_call = matches!(self.peek(), Some(t) if t.kind == TokenKind::Open);
                if name == SQRT {
                    if !is_call {
                        return Err(self.expected("'(' after sqrt"));
                    }
                    self.position += 1;
                    let (inner, height) = self.sum()?;
                    self.close()?;
                    return self.node(Node::Sqrt(Box::new(inner)), &[height]);
                }
                if is_call {
                    return Err(ExpressionError::UnknownFunction {
                        column: token.column,
                        name,
                    });
                }
                match self.symbols.iter().position(|s| *s == name) {
                    Some(k) => {
                        self.used.push(k);
                        Ok((Node::Symbol(k), 1))
                    }
                    None => Err(ExpressionError::UnknownSymbol {
                        column: token.column,
                        name,
                    }),
                }
            }
            TokenKind::Operator(_) | TokenKind::Close => Err(self.expected(OPERAND)),
        }
    }

    fn close(&mut self) -> Result<(), ExpressionError> {
        match self.peek() {
            Some(Token {
                kind: TokenKind::Close,
                ..
            }) => {
                self.position += 1;
                Ok(())
            }
            _ => Err(self.expected("')'")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(text: &str, symbols: &[&str], values: &[f64]) -> f64 {
        Expression::parse(text, symbols).unwrap().eval_with(values)
    }

    fn value(text: &str) -> f64 {
        eval(text, &[], &[])
    }

    #[test]
    fn division_is_floating_point() {
        assert_eq!(value("1/12"), 1.0 / 12.0);
        assert!((value("1/12") - 0.083_333_333_333_333_33).abs() < 1e-17);
        assert_eq!(eval("l1 * l1 / 12", &["l1"], &[2.0]), 4.0 / 12.0);
    }

    #[test]
    fn precedence_and_associativity_follow_mathematics() {
        assert_eq!(value("1 + 2 * 3"), 7.0);
        assert_eq!(value("(1 + 2) * 3"), 9.0);
        assert_eq!(value("8 / 4 / 2"), 1.0);
        assert_eq!(value("8 - 4 - 2"), 2.0);
        assert_eq!(value("2^3^2"), 512.0);
        assert_eq!(value("2 * 3^2"), 18.0);
        assert_eq!(value("-2^2"), -4.0);
        assert_eq!(value("(-2)^2"), 4.0);
        assert_eq!(value("2^-1"), 0.5);
        assert_eq!(value("2 * -3"), -6.0);
        assert_eq!(value("--3"), 3.0);
        assert_eq!(value("+3 - -3"), 6.0);
        assert_eq!(eval("-a^2", &["a"], &[3.0]), -9.0);
        assert_eq!(value("4^0.5"), 2.0);
    }

    #[test]
    fn sqrt_and_numbers() {
        assert_eq!(value("sqrt(16)"), 4.0);
        assert_eq!(value("-sqrt(4) * 2"), -4.0);
        assert_eq!(value("sqrt(2)^2"), 2.0f64.sqrt().powi(2));
        assert!(value("sqrt(-1)").is_nan());
        assert_eq!(value("1e-3 + 2.5E2 + .5 + 5."), 0.001 + 250.0 + 0.5 + 5.0);
        assert_eq!(value("1.5e+1"), 15.0);
    }

    #[test]
    fn symbols_are_numbered_and_listed() {
        let e = Expression::parse("b * (a + b) + c0_", &["a", "b", "c0_"]).unwrap();
        assert_eq!(e.symbols(), &[0, 1, 2]);
        assert_eq!(e.eval_with(&[1.0, 2.0, 10.0]), 16.0);
        assert_eq!(e.to_string(), "b * (a + b) + c0_");
        // A dotted name can never be matched by an identifier.
        let e = Expression::parse("x", &["link.a.mass", "x"]).unwrap();
        assert_eq!(e.symbols(), &[1]);
    }

    #[test]
    fn errors_say_where_and_what() {
        let err = |t: &str| Expression::parse(t, &["l1"]).unwrap_err();
        assert_eq!(err("   "), ExpressionError::Empty);
        assert_eq!(
            err("l1 * l2"),
            ExpressionError::UnknownSymbol {
                column: 6,
                name: "l2".to_string()
            }
        );
        assert!(matches!(
            err("sin(l1)"),
            ExpressionError::UnknownFunction { column: 1, .. }
        ));
        assert!(matches!(
            err("1.2.3"),
            ExpressionError::BadNumber { column: 1, .. }
        ));
        assert!(matches!(
            err("1e"),
            ExpressionError::BadNumber { column: 1, .. }
        ));
        assert!(matches!(
            err("l1 % 2"),
            ExpressionError::UnexpectedCharacter { character: '%', .. }
        ));
        let msg = err("(l1 + 1").to_string();
        assert!(
            msg.contains("expected ')' at column 8, found the end"),
            "{msg}"
        );
        let msg = err("l1 +").to_string();
        assert!(msg.contains("expected a number, a symbol"), "{msg}");
        let msg = err("l1 l1").to_string();
        assert!(msg.contains("expected an operator or the end"), "{msg}");
        let msg = err("sqrt 4").to_string();
        assert!(msg.contains("'(' after sqrt"), "{msg}");
        assert!(err("l1)").to_string().contains("found ')'"));
    }

    /// 100 000 levels of nesting, each way an expression can nest, on a thread with a small stack:
    /// a clear error at the limit, never a stack overflow.
    #[test]
    fn hostile_nesting_is_refused_not_a_stack_overflow() {
        const HOSTILE: usize = 100_000;
        /// Far below the 2 MiB of a test thread and the 8 MiB of the main thread.
        const SMALL_STACK_BYTES: usize = 512 * 1024;
        let cases: Vec<(&str, String)> = vec![
            (
                "parentheses",
                format!("{}l1{}", "(".repeat(HOSTILE), ")".repeat(HOSTILE)),
            ),
            ("unary minus", format!("{}l1", "-".repeat(HOSTILE))),
            ("unary plus", format!("{}l1", "+".repeat(HOSTILE))),
            (
                "sqrt",
                format!("{}l1{}", "sqrt(".repeat(HOSTILE), ")".repeat(HOSTILE)),
            ),
            ("exponents", vec!["l1"; HOSTILE].join("^")),
            ("a sum chain", vec!["l1"; HOSTILE].join("+")),
            ("a product chain", vec!["l1"; HOSTILE].join("*")),
            ("unclosed parentheses", "(".repeat(HOSTILE)),
        ];
        let handle = std::thread::Builder::new()
            .stack_size(SMALL_STACK_BYTES)
            .spawn(move || {
                for (what, text) in &cases {
                    let e = Expression::parse(text, &["l1"]).unwrap_err();
                    assert!(
                        matches!(
                            e,
                            ExpressionError::TooDeep {
                                limit: MAX_DEPTH,
                                ..
                            }
                        ),
                        "{what}: {e}"
                    );
                    assert!(
                        e.to_string().contains("nests deeper than 256 levels"),
                        "{e}"
                    );
                }
                // Just inside the limit, every shape parses and evaluates.
                let inside = MAX_DEPTH - 1;
                let nested = format!("{}l1{}", "(".repeat(inside), ")".repeat(inside));
                assert_eq!(eval(&nested, &["l1"], &[2.0]), 2.0);
                let negated = format!("{}l1", "-".repeat(inside));
                assert_eq!(eval(&negated, &["l1"], &[2.0]), -2.0);
                let chain = vec!["l1"; MAX_DEPTH].join("+");
                assert_eq!(eval(&chain, &["l1"], &[1.0]), MAX_DEPTH as f64);
            })
            .unwrap();
        handle.join().unwrap();
    }
}
