//! Raw device readings: symbols normalised to [`InputEvent`]s (one symbol from one device at one
//! time) for the sequence recognizer, and proportional readings (sticks, head cap, arrow keys)
//! for driving.

use serde::{Deserialize, Serialize};

use crate::InterfaceError;

/// The input devices of the multimodal interface (thesis 3.3.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Device {
    /// Analogue joystick.
    Joystick,
    /// Gamepad buttons.
    Gamepad,
    /// Keyboard keys.
    Keyboard,
    /// Head gestures from a head-worn accelerometer.
    HeadGesture,
    /// Voice commands, already turned to text by the speech recogniser.
    Voice,
    /// Facial-expression labels from the face tracker.
    Face,
    /// A drive panel in another container (the services' dashboard), as `drive` requests over
    /// the bus from an agent of [`crate::InterfaceConfig::remote_drivers`].
    Remote,
}

/// One normalised input: a symbol of one device (`up`, `a`, `nod-left`, `go`, `smile`).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct InputEvent {
    /// Which device produced it.
    pub device: Device,
    /// The device's symbol, lower case.
    pub symbol: String,
    /// When, ms of the interface clock.
    pub t_ms: u64,
}

/// A raw reading from a device, before normalisation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "device", rename_all = "kebab-case")]
pub enum RawInput {
    /// Joystick deflection, each axis in [-1, 1] (x right, y forward): proportional driving.
    Joystick {
        /// Right deflection.
        x: f64,
        /// Forward deflection.
        y: f64,
    },
    /// A gamepad's left stick, as the joystick: proportional driving.
    GamepadStick {
        /// Right deflection.
        x: f64,
        /// Forward deflection.
        y: f64,
    },
    /// The head cap's inclinometer (thesis 3.3.1) used as a proportional controller: forward
    /// and rightward head tilt, rad.
    HeadCap {
        /// Forward tilt, rad.
        pitch_rad: f64,
        /// Rightward tilt, rad.
        roll_rad: f64,
    },
    /// Which arrow keys are held: proportional driving at a fixed deflection.
    Arrows {
        /// Up held.
        up: bool,
        /// Down held.
        down: bool,
        /// Left held.
        left: bool,
        /// Right held.
        right: bool,
    },
    /// A gamepad button name.
    Gamepad {
        /// Button (`a`, `b`, `start`...).
        button: String,
    },
    /// A keyboard key name.
    Keyboard {
        /// Key (`up`, `space`, `g`...).
        key: String,
    },
    /// Head accelerometer sample, m/s^2 in the head frame (x right, y forward).
    HeadGesture {
        /// Lateral acceleration.
        ax_mps2: f64,
        /// Forward acceleration.
        ay_mps2: f64,
    },
    /// Recognised speech.
    Voice {
        /// The words heard.
        text: String,
    },
    /// A facial-expression label.
    Face {
        /// The label (`smile`, `blink`, `mouth-open`...).
        label: String,
    },
}

/// Head acceleration under which no gesture is recognised, m/s^2.
pub const HEAD_THRESHOLD_MPS2: f64 = 2.0;

fn symbol(device: Device, text: &str) -> Result<String, InterfaceError> {
    let symbol = text.trim().to_ascii_lowercase();
    if symbol.is_empty()
        || symbol.len() > 64
        || !symbol
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
    {
        return Err(InterfaceError::BadSymbol {
            device,
            symbol: text.to_string(),
        });
    }
    Ok(symbol)
}

fn direction(x: f64, y: f64, threshold: f64) -> Option<&'static str> {
    if !(x.is_finite() && y.is_finite()) || x.abs().max(y.abs()) < threshold {
        return None;
    }
    Some(if y.abs() >= x.abs() {
        if y > 0.0 { "up" } else { "down" }
    } else if x > 0.0 {
        "right"
    } else {
        "left"
    })
}

impl RawInput {
    /// The events this reading stands for at `t_ms`: none for a proportional reading or a still
    /// head, one per word for speech. Names with characters other than letters, digits, `-` and
    /// `_` are refused.
    pub fn normalise(&self, t_ms: u64) -> Result<Vec<InputEvent>, InterfaceError> {
        let event = |device, symbol: String| InputEvent {
            device,
            symbol,
            t_ms,
        };
        Ok(match self {
            RawInput::Joystick { .. }
            | RawInput::GamepadStick { .. }
            | RawInput::HeadCap { .. }
            | RawInput::Arrows { .. } => Vec::new(),
            RawInput::HeadGesture { ax_mps2, ay_mps2 } => {
                direction(*ax_mps2, *ay_mps2, HEAD_THRESHOLD_MPS2)
                    .map(|d| event(Device::HeadGesture, format!("head-{d}")))
                    .into_iter()
                    .collect()
            }
            RawInput::Gamepad { button } => {
                vec![event(Device::Gamepad, symbol(Device::Gamepad, button)?)]
            }
            RawInput::Keyboard { key } => {
                vec![event(Device::Keyboard, symbol(Device::Keyboard, key)?)]
            }
            RawInput::Face { label } => vec![event(Device::Face, symbol(Device::Face, label)?)],
            RawInput::Voice { text } => text
                .split_whitespace()
                .map(|w| w.trim_matches(|c: char| c.is_ascii_punctuation()))
                .filter(|w| !w.is_empty())
                .map(|w| symbol(Device::Voice, w).map(|s| event(Device::Voice, s)))
                .collect::<Result<_, _>>()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readings_become_symbols_and_sticks_drive() {
        let j = RawInput::Joystick { x: 0.1, y: 0.9 };
        assert!(
            j.normalise(5).unwrap().is_empty(),
            "a stick drives, it is no symbol"
        );
        let mapping = crate::DriveMapping::default();
        assert!(mapping.command(&j).is_some());
        let face = RawInput::Face {
            label: "smile".into(),
        };
        assert!(mapping.command(&face).is_none(), "a symbol does not drive");
        let h = RawInput::HeadGesture {
            ax_mps2: -3.0,
            ay_mps2: 1.0,
        }
        .normalise(0)
        .unwrap();
        assert_eq!(h[0].symbol, "head-left");
        let v = RawInput::Voice {
            text: "Go, kitchen!".into(),
        }
        .normalise(0)
        .unwrap();
        assert_eq!(
            v.iter().map(|e| e.symbol.as_str()).collect::<Vec<_>>(),
            ["go", "kitchen"]
        );
        assert!(matches!(
            RawInput::Keyboard { key: "a b".into() }.normalise(0),
            Err(InterfaceError::BadSymbol {
                device: Device::Keyboard,
                ..
            })
        ));
    }
}
