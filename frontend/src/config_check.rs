//! Range checks shared by the configuration sections: each names the bad
//! key by the `field` it is given (its TOML path) in a
//! [`FrontendError::InvalidConfig`]; none changes a value.

use crate::error::FrontendError;
use crate::matcher::SearchWindow;

/// The largest translation half-width or standard deviation of a
/// [`SearchWindow`] in the config, metres. A search window's cost grows
/// with its area in image cells, and a sonar sees at most a few hundred
/// metres, so a larger value is a typing error that would only make a run
/// hang.
pub const MAX_WINDOW_M: f64 = 1000.0;

/// Checks that `value` is finite and within `[lo, hi]`.
pub fn check_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<(), FrontendError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(FrontendError::config(
            field,
            format!("must be finite and within [{lo}, {hi}], got {value}"),
        ))
    }
}

/// Checks that `value` is finite and > 0: a size, a noise or a scale
/// that divides or multiplies, which 0, a negative value or NaN would turn
/// into an empty, infinite or undefined result.
pub fn check_positive(field: &str, value: f64) -> Result<(), FrontendError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(FrontendError::config(
            field,
            format!("must be finite and > 0, got {value}"),
        ))
    }
}

/// Checks a window's values, naming the element and its axis
/// (`loops.gate.min_window[2] (theta_rad)`): finite, `0 <= x_m, y_m <=`
/// [`MAX_WINDOW_M`], `0 <= theta_rad <= π`.
pub fn check_window(field: &str, window: &SearchWindow) -> Result<(), FrontendError> {
    check_range(&axis_field(field, 0), window.x_m, 0.0, MAX_WINDOW_M)?;
    check_range(&axis_field(field, 1), window.y_m, 0.0, MAX_WINDOW_M)?;
    check_range(
        &axis_field(field, 2),
        window.theta_rad,
        0.0,
        std::f64::consts::PI,
    )
}

/// The name of element `i` of the window key `field`, with its axis.
fn axis_field(field: &str, i: usize) -> String {
    let axis = ["x_m", "y_m", "theta_rad"][i.min(2)];
    format!("{field}[{i}] ({axis})")
}

/// Checks that `window` is positive on every axis (a search over a window
/// of zero width finds nothing; a standard deviation of zero makes an
/// information matrix infinite).
pub fn check_positive_window(field: &str, window: &SearchWindow) -> Result<(), FrontendError> {
    for (i, (_, value)) in window.axes().into_iter().enumerate() {
        if value <= 0.0 {
            return Err(FrontendError::config(
                axis_field(field, i),
                format!("must be > 0, got {value}"),
            ));
        }
    }
    Ok(())
}

/// Checks `lower <= upper` on every axis, naming both keys (`min_window`
/// against `max_window`: a clamp between them needs the order).
pub fn check_window_order(
    lower_field: &str,
    lower: &SearchWindow,
    upper_field: &str,
    upper: &SearchWindow,
) -> Result<(), FrontendError> {
    for (i, ((_, lo), (_, hi))) in lower.axes().into_iter().zip(upper.axes()).enumerate() {
        if lo > hi {
            return Err(FrontendError::config(
                axis_field(lower_field, i),
                format!(
                    "{lo} exceeds {} = {hi}; it must not",
                    axis_field(upper_field, i)
                ),
            ));
        }
    }
    Ok(())
}
