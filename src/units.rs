//! Numbers as people read them in messages and tables: `1e300`, not three hundred digits.

use std::fmt;

/// Displays an `f64` in its shortest exact form, in exponent notation outside [1e-4, 1e9)
/// (Rust's `{}` never uses an exponent, so 1e300 would print 301 digits and 2e-9 ten zeros).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Short(pub f64);

impl fmt::Display for Short {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        if x == 0.0 || !x.is_finite() || (1e-4..1e9).contains(&x.abs()) {
            write!(f, "{x}")
        } else {
            write!(f, "{x:e}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Short;

    #[test]
    fn numbers_stay_short() {
        assert_eq!(Short(1e300).to_string(), "1e300");
        assert_eq!(Short(-2.1839e-9).to_string(), "-2.1839e-9");
        assert_eq!(Short(25400.0).to_string(), "25400");
        assert_eq!(Short(0.5).to_string(), "0.5");
        assert_eq!(Short(0.0).to_string(), "0");
        assert_eq!(Short(f64::NAN).to_string(), "NaN");
        assert_eq!(Short(f64::INFINITY).to_string(), "inf");
        assert_eq!(Short(4.3e10).to_string(), "4.3e10");
    }
}
