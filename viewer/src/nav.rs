//! City navigation shared by the native and web viewers: walk or fly, and a movement speed
//! proportional to the eye's height above the content's ground.

/// Movement speed per metre of height above the content's ground, 1/s (Shift: faster).
pub const SPEED_PER_HEIGHT: f64 = 1.0;
/// Heights below this (metres) move at this height's speed: a walk at street level.
pub const MIN_SPEED_HEIGHT: f64 = 2.0;

/// How W/S/A/D move the eye.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Horizontally whatever the pitch: the eye height stays (Q/E do nothing).
    Walk,
    /// Along the view direction; Q/E down and up.
    Fly,
}

impl Mode {
    /// The other mode (the F key).
    pub fn toggled(self) -> Mode {
        match self {
            Mode::Walk => Mode::Fly,
            Mode::Fly => Mode::Walk,
        }
    }

    /// "walk" or "fly".
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Walk => "walk",
            Mode::Fly => "fly",
        }
    }
}

/// Speed (metres per second, without Shift) at `height` metres above the ground.
pub fn speed_at(height: f64) -> f64 {
    SPEED_PER_HEIGHT
        * if height.is_finite() {
            height.max(MIN_SPEED_HEIGHT)
        } else {
            MIN_SPEED_HEIGHT
        }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_is_proportional_to_height_with_a_street_floor() {
        assert_eq!(speed_at(500.0) / speed_at(50.0), 10.0);
        assert_eq!(speed_at(1.7), speed_at(MIN_SPEED_HEIGHT));
        assert_eq!(speed_at(-3.0), speed_at(MIN_SPEED_HEIGHT));
        assert_eq!(speed_at(f64::NAN), speed_at(MIN_SPEED_HEIGHT));
        assert_eq!(Mode::Walk.toggled(), Mode::Fly);
        assert_eq!(Mode::Fly.toggled().as_str(), "walk");
    }
}
