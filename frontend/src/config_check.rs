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

/// Checks a window's values, naming the axis: finite, `0 <= x_m, y_m <=`
/// [`MAX_WINDOW_M`], `0 <= theta_rad <= π`.
pub fn check_window(field: &str, window: &SearchWindow) -> Result<(), FrontendError> {
    check_range(&format!("{field}.x_m"), window.x_m, 0.0, MAX_WINDOW_M)?;
    check_range(&format!("{field}.y_m"), window.y_m, 0.0, MAX_WINDOW_M)?;
    check_range(
        &format!("{field}.theta_rad"),
        window.theta_rad,
        0.0,
        std::f64::consts::PI,
    )
}

/// Checks that `window` is positive on every axis (a search over a window
/// of zero width finds nothing; a standard deviation of zero makes an
/// information matrix infinite).
pub fn check_positive_window(field: &str, window: &SearchWindow) -> Result<(), FrontendError> {
    for (axis, value) in window.axes() {
        if value <= 0.0 {
            return Err(FrontendError::config(
                format!("{field}.{axis}"),
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
    for ((axis, lo), (_, hi)) in lower.axes().into_iter().zip(upper.axes()) {
        if lo > hi {
            return Err(FrontendError::config(
                format!("{lower_field}.{axis}"),
                format!("{lo} exceeds {upper_field}.{axis} = {hi}; it must not"),
            ));
        }
    }
    Ok(())
}
