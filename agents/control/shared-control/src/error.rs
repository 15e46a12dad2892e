//! Errors of the control library.

/// Why a controller could not produce a command.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ControlError {
    /// A command had a NaN or infinite speed.
    #[error(
        "command ({linear_mps} m/s, {angular_radps} rad/s) is not finite; check the input device"
    )]
    NonFiniteCommand {
        /// Linear speed given.
        linear_mps: f64,
        /// Angular speed given.
        angular_radps: f64,
    },
    /// A sensor reading was NaN, infinite or negative.
    #[error("{sensor} reading {index} is {value} m; ranges must be finite and >= 0")]
    BadReading {
        /// Which sensor kind ("sonar", "laser point", "speed").
        sensor: &'static str,
        /// Index in its array.
        index: usize,
        /// The value.
        value: f64,
    },
    /// The number of sonar readings does not match the mounts the controller was built with.
    #[error("got {got} sonar readings for {expected} mounts")]
    SonarCount {
        /// Mounts configured.
        expected: usize,
        /// Readings given.
        got: usize,
    },
    /// A parameter is out of its range.
    #[error("parameter {name} = {value} is invalid: {why}")]
    BadParameter {
        /// Parameter name, with unit suffix.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must satisfy.
        why: &'static str,
    },
    /// A tactical action got a pose or target that is not finite.
    #[error("{what} is not finite: ({x}, {y}, {theta})")]
    NonFinitePose {
        /// Which pose ("chair pose", "target").
        what: &'static str,
        /// x, m.
        x: f64,
        /// y, m.
        y: f64,
        /// Heading, rad.
        theta: f64,
    },
    /// A circuit needs at least two distinct waypoints.
    #[error("circuit has {count} waypoints; at least 2 distinct ones are needed")]
    ShortCircuit {
        /// Waypoints given.
        count: usize,
    },
    /// A statistical test got samples of different lengths.
    #[error("paired samples differ in length: {left} vs {right}")]
    UnpairedSamples {
        /// First sample length.
        left: usize,
        /// Second sample length.
        right: usize,
    },
}

/// Checks one range reading.
pub(crate) fn check_range(
    sensor: &'static str,
    index: usize,
    value: f64,
) -> Result<f64, ControlError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(ControlError::BadReading {
            sensor,
            index,
            value,
        })
    }
}

/// Checks a parameter is finite and positive.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<f64, ControlError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ControlError::BadParameter {
            name,
            value,
            why: "must be finite and > 0",
        })
    }
}
