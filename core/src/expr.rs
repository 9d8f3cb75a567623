//! Load values that vary with position and time (issue 23): a load's `value` is a number or a
//! string holding an expression of `x`, `y` (the reference coordinates of the point where the
//! load acts) and `t` (time), e.g. the hydrostatic pressure `"2.65e-3 * 980 * (10 - y)"` or a
//! ramp `"min(t / 2, 1)"`. A stage's level still multiplies the value.
//!
//! Expressions are parsed and evaluated by the `exmex` crate (MIT/Apache-2.0, maintained, a
//! compiled flat expression evaluated from a slice of variable values): `+ - * / ^`, `sin cos
//! tan asin acos atan sinh cosh tanh exp ln (= log) log10 log2 sqrt cbrt abs signum floor ceil
//! round`, `min(a, b) max(a, b) atan2(y, x)`, and the constants `PI` (`π`), `TAU`, `E`.
//! (evalexpr, the other well-kept choice, is AGPL-licensed.) Variables other than `x`, `y`, `t`
//! are refused when the scene is validated, naming the key. exmex binds a unary minus tighter
//! than `^` (`-2^2` is 4 there, -4 in mathematics), so a sign written directly before a power
//! (`-x^2`, `exp(-y^2)`) is refused with the bracketed forms to choose from, never read either way.
//!
//! `t` is the run's time. In a stage marched to equilibrium (not `dynamic`) that is the
//! relaxation's pseudo-time, which depends on the damping and dt: such a scene gets a warning
//! (a load of t belongs to a `dynamic = true` stage).
//!
//! When an expression is evaluated (solver/loads.rs): an edge load is integrated over each face
//! with 2-point Gauss quadrature and linear shape functions (exact for a value linear along the
//! face, the consistent nodal forces otherwise); an expression without `t` is evaluated once per
//! face when the scene is built (a level change only rescales it, as for a constant); one with
//! `t` is evaluated at every step, for that load only, at the step's time. A value that is not
//! finite, or beyond 1e100, stops the run with the load's key, the expression and the point.
use std::fmt;

use exmex::prelude::*;
use exmex::{literal_matcher_from_pattern, FloatOpsFactory, MatchLiteral};
use serde::de::{self, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A load value as written in a scene: a number, or an expression of x, y and t.
#[derive(Clone, Debug, PartialEq)]
pub enum LoadValue {
    Number(f64),
    Expr(String),
}

impl Serialize for LoadValue {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            LoadValue::Number(v) => s.serialize_f64(*v),
            LoadValue::Expr(e) => s.serialize_str(e),
        }
    }
}

impl<'de> Deserialize<'de> for LoadValue {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<LoadValue, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = LoadValue;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number, or a string with an expression of x, y and t")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<LoadValue, E> {
                Ok(LoadValue::Number(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<LoadValue, E> {
                Ok(LoadValue::Number(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<LoadValue, E> {
                Ok(LoadValue::Number(v as f64))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<LoadValue, E> {
                Ok(LoadValue::Expr(v.to_string()))
            }
        }
        d.deserialize_any(V)
    }
}

// Numbers with an exponent (2.65e-3): exmex's default literal pattern has none.
literal_matcher_from_pattern!(SciMatcher, r"^(\.?[0-9]+(\.[0-9]+)?([eE][+-]?[0-9]+)?)");
type Ex = FlatEx<f64, FloatOpsFactory<f64>, SciMatcher>;

/// A compiled load value.
#[derive(Clone, Debug)]
pub enum Field {
    Const(f64),
    Expr {
        text: String,
        ex: Ex,
        /// For each variable of `ex` (in its order): 0 = x, 1 = y, 2 = t.
        order: Vec<u8>,
        uses_t: bool,
    },
}

impl LoadValue {
    /// Compiles the value; the error (for the key's message) says what is wrong.
    pub fn compile(&self) -> Result<Field, String> {
        match self {
            LoadValue::Number(v) => Ok(Field::Const(*v)),
            LoadValue::Expr(text) => {
                if let Some(at) = sign_before_power(text) {
                    return Err(format!("= \"{text}\": the sign at character {} applies to a power; write -(a^b) or (-a)^b (the expression parser would read -a^b as (-a)^b)", at + 1));
                }
                // A parser panic on odd input becomes the key's error, never a crash.
                let parsed = std::panic::catch_unwind(|| Ex::parse(text)).map_err(|_| format!("= \"{text}\" could not be parsed (the expression parser failed on it)"))?;
                let ex = parsed.map_err(|e| format!("= \"{text}\" is not an expression of x, y and t: {e}"))?;
                let mut order = Vec::new();
                for v in ex.var_names() {
                    order.push(match v.as_str() {
                        "x" => 0,
                        "y" => 1,
                        "t" => 2,
                        other => return Err(format!("= \"{text}\" uses the variable \"{other}\"; an expression may use x, y (the reference coordinates) and t (time)")),
                    });
                }
                let uses_t = order.contains(&2);
                Ok(Field::Expr { text: text.clone(), ex, order, uses_t })
            }
        }
    }
}

/// The byte position of a unary sign whose operand is raised to a power (`-x^2`, `2*-(y)^3`),
/// or None. An operand is a number, a name, a bracketed group, or a function call.
fn sign_before_power(text: &str) -> Option<usize> {
    let b = text.as_bytes();
    let skip_ws = |mut i: usize| {
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        i
    };
    let close = |mut i: usize| {
        // From an opening bracket to just past its match.
        let mut depth = 0;
        while i < b.len() {
            match b[i] {
                b'(' => depth += 1,
                b')' => {
                    depth -= 1;
                    if depth == 0 {
                        return i + 1;
                    }
                }
                _ => {}
            }
            i += 1;
        }
        i
    };
    let mut prev: Option<u8> = None;
    for i in 0..b.len() {
        let c = b[i];
        if c.is_ascii_whitespace() {
            continue;
        }
        let unary = (c == b'-' || c == b'+') && prev.is_none_or(|p| b"(,+-*/^".contains(&p)) && !prev.is_some_and(|p| p.is_ascii_alphanumeric() || p == b'.' || p == b')');
        // A sign inside a number's exponent (2.5e-3) follows a letter: not unary.
        if unary {
            let mut j = skip_ws(i + 1);
            if j < b.len() && b[j] == b'(' {
                j = close(j);
            } else {
                while j < b.len()
                    && (b[j].is_ascii_alphanumeric()
                        || b[j] == b'_'
                        || b[j] == b'.'
                        || ((b[j] == b'-' || b[j] == b'+') && j > 0 && (b[j - 1] == b'e' || b[j - 1] == b'E') && j > 1 && b[j - 2].is_ascii_digit()))
                {
                    j += 1;
                }
                let k = skip_ws(j);
                if k < b.len() && b[k] == b'(' {
                    j = close(k);
                }
            }
            let k = skip_ws(j);
            if k < b.len() && b[k] == b'^' {
                return Some(i);
            }
        }
        prev = Some(c);
    }
    None
}

impl Field {
    /// The value at a point and time; NaN when the expression cannot be evaluated there.
    pub fn at(&self, x: f64, y: f64, t: f64) -> f64 {
        match self {
            Field::Const(v) => *v,
            Field::Expr { ex, order, .. } => {
                let all = [x, y, t];
                let mut vals = [0.0; 3];
                for (k, &o) in order.iter().enumerate() {
                    vals[k] = all[o as usize];
                }
                ex.eval(&vals[..order.len()]).unwrap_or(f64::NAN)
            }
        }
    }

    /// Whether the value changes with time.
    pub fn uses_t(&self) -> bool {
        matches!(self, Field::Expr { uses_t: true, .. })
    }

    /// The constant, when the value is one.
    pub fn constant(&self) -> Option<f64> {
        match self {
            Field::Const(v) => Some(*v),
            Field::Expr { .. } => None,
        }
    }

    /// The expression's text (empty for a constant), for messages.
    pub fn text(&self) -> &str {
        match self {
            Field::Const(_) => "",
            Field::Expr { text, .. } => text,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: the expressions' own arithmetic, evaluated by hand.
    #[test]
    fn expressions_of_x_y_t_evaluate_and_others_are_refused() {
        let f = LoadValue::Expr("2 * x - y^2 + 3 * t".into()).compile().unwrap();
        assert_eq!(f.at(1.5, 2.0, 0.5), 2.0 * 1.5 - 4.0 + 1.5);
        assert!(f.uses_t());
        let g = LoadValue::Expr("-2.65e-3 * 980 * (10 - y)".into()).compile().unwrap();
        assert!((g.at(7.0, 4.0, 9.0) - (-2.65e-3 * 980.0 * 6.0)).abs() < 1e-12 && !g.uses_t());
        let c = LoadValue::Expr("cos(PI)".into()).compile().unwrap();
        assert!((c.at(0.0, 0.0, 0.0) + 1.0).abs() < 1e-15);
        assert_eq!(LoadValue::Number(4.0).compile().unwrap().constant(), Some(4.0));
        let e = LoadValue::Expr("x + z".into()).compile().unwrap_err();
        assert!(e.contains("\"z\"") && e.contains("x, y"), "{e}");
        assert!(LoadValue::Expr("x +* (".into()).compile().is_err());
        assert!(LoadValue::Expr("1 / x".into()).compile().unwrap().at(0.0, 0.0, 0.0).is_infinite());
        let m = LoadValue::Expr("min(t / 2, 1) + max(x, y) + atan2(1, 1)".into()).compile().unwrap();
        assert!((m.at(3.0, 2.0, 1.0) - (0.5 + 3.0 + std::f64::consts::FRAC_PI_4)).abs() < 1e-15);
    }

    /// A sign directly before a power is refused (the parser would read -x^2 as (-x)^2 = +x^2);
    /// bracketed forms, binary minus and exponents of numbers pass. Reference: the mathematical
    /// reading, -x^2 = -(x^2).
    #[test]
    fn a_sign_before_a_power_is_refused() {
        for bad in ["-x^2", "exp(-y^2)", "2 * -x ^ 3", "-(x + 1)^2", "1 + -sin(x)^2", "-2.5e-3^2"] {
            let e = LoadValue::Expr(bad.into()).compile().unwrap_err();
            assert!(e.contains("applies to a power"), "{bad}: {e}");
        }
        for good in ["-(x^2)", "(-x)^2", "exp(-(y^2))", "1 - x^2", "2.5e-3 * y^2", "-x * 2", "x^-1", "y - 2e-3^2"] {
            assert!(LoadValue::Expr(good.into()).compile().is_ok(), "{good}");
        }
        let f = LoadValue::Expr("1 - x^2".into()).compile().unwrap();
        assert_eq!(f.at(3.0, 0.0, 0.0), -8.0);
    }
}
