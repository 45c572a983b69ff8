//! Range checks for configuration numbers: each names the key, the allowed range and the unit,
//! so `NaN`, a negative timeout or an absurd speed is refused with a message that says where.
//!
//! In: a dotted key, a value, its range and unit. Out: `Ok` or `(key, message)`, the form
//! [`crate::config::ConfigError::Invalid`] is built from.

/// A refused value: the dotted key and why.
pub type Refusal = (String, String);

/// `value` must be finite and within `min..=max` (`min_exclusive`: strictly above `min`).
pub fn within(
    key: &str,
    value: f64,
    (min, max): (f64, f64),
    min_exclusive: bool,
    unit: &str,
) -> Result<(), Refusal> {
    let above = if min_exclusive {
        value > min
    } else {
        value >= min
    };
    if value.is_finite() && above && value <= max {
        return Ok(());
    }
    let low = if min_exclusive { "above" } else { "at least" };
    Err((
        key.to_string(),
        format!("must be {low} {min} and at most {max} {unit}, got {value}"),
    ))
}

/// Strictly positive and at most `max` (speeds, rates, timeouts).
pub fn positive(key: &str, value: f64, max: f64, unit: &str) -> Result<(), Refusal> {
    within(key, value, (0.0, max), true, unit)
}

/// Zero or more, at most `max` (gains, delays that may be off).
pub fn non_negative(key: &str, value: f64, max: f64, unit: &str) -> Result<(), Refusal> {
    within(key, value, (0.0, max), false, unit)
}

/// A whole number within `min..=max`.
pub fn count(key: &str, value: usize, (min, max): (usize, usize)) -> Result<(), Refusal> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err((
            key.to_string(),
            format!("must be {min} to {max}, got {value}"),
        ))
    }
}

/// Every component of a vector with [`non_negative`].
pub fn non_negative3(key: &str, v: &[f64; 3], max: f64, unit: &str) -> Result<(), Refusal> {
    v.iter().try_for_each(|&c| non_negative(key, c, max, unit))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_infinity_and_out_of_range_values_name_the_key_and_unit() {
        let (key, msg) = positive("behaviors.arm_timeout_s", f64::NAN, 600.0, "s").unwrap_err();
        assert_eq!(key, "behaviors.arm_timeout_s");
        assert!(msg.contains("600 s") && msg.contains("NaN"), "{msg}");
        assert!(positive("k", 0.0, 1.0, "m").is_err());
        assert!(positive("k", 1.0, 1.0, "m").is_ok());
        assert!(non_negative("k", 0.0, 1.0, "m").is_ok());
        assert!(non_negative("k", -0.1, 1.0, "m").is_err());
        assert!(non_negative("k", f64::INFINITY, f64::INFINITY, "m").is_err());
        assert!(count("k", 0, (1, 5)).is_err());
        assert!(non_negative3("k", &[0.0, 1.0, -1.0], 5.0, "").is_err());
    }
}
