//! Option values by name: the enums a command line or a plan file spells as words (`auto`,
//! `moment`, `best`) list their names and one-line help here, so front ends need no copy.

/// An enum whose every value has a lower-case name and a help line.
pub trait Named: Copy + Sized + 'static {
    /// Every value, in the order help lists them.
    const ALL: &'static [Self];
    /// The value's name (as typed on a command line or stored in a plan).
    fn name(self) -> &'static str;
    /// What the value means, one sentence.
    fn help(self) -> &'static str;
    /// The value called `s`, if any.
    fn from_name(s: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|v| v.name() == s)
    }
}

/// Implements [`Named`] for an enum from `Variant => ("name", "help")` pairs.
#[macro_export]
macro_rules! named {
    ($t:ty { $($v:ident => ($name:literal, $help:literal)),+ $(,)? }) => {
        impl $crate::named::Named for $t {
            const ALL: &'static [Self] = &[$(<$t>::$v),+];
            fn name(self) -> &'static str {
                match self { $(<$t>::$v => $name),+ }
            }
            fn help(self) -> &'static str {
                match self { $(<$t>::$v => $help),+ }
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::Named;

    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Shape {
        Round,
        Square,
    }
    crate::named!(Shape { Round => ("round", "Curved."), Square => ("square", "Four sides.") });

    #[test]
    fn names_round_trip() {
        for &v in Shape::ALL {
            assert_eq!(Shape::from_name(v.name()), Some(v));
        }
        assert_eq!(Shape::from_name("Round"), None);
        assert_eq!(Shape::Square.help(), "Four sides.");
    }
}
