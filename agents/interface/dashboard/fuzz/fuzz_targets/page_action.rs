//! Any websocket text a page may send: the action parser never panics, and an action it accepts
//! has finite numbers and reads back as the same kind of action from its own JSON (numbers may
//! move by one unit in the last place: serde_json parses floats best-effort).
#![no_main]

use iw_dashboard::{DriveInput, PageAction};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = std::str::from_utf8(bytes) else { return };
    let Ok(action) = serde_json::from_str::<PageAction>(text) else { return };
    let numbers: Vec<f64> = match &action {
        PageAction::Goal { x, y, .. } => vec![*x, *y],
        PageAction::Drive { input, .. } => match *input {
            DriveInput::Stick { x, y } | DriveInput::Gamepad { x, y } => vec![x, y],
            DriveInput::Head { pitch, roll } => vec![pitch, roll],
            DriveInput::Keys { .. } => vec![],
        },
        _ => vec![],
    };
    assert!(numbers.iter().all(|v| v.is_finite()), "{action:?}");
    let again = serde_json::to_string(&action).expect("an action serialises");
    let back = serde_json::from_str::<PageAction>(&again).expect("it parses back");
    assert_eq!(std::mem::discriminant(&back), std::mem::discriminant(&action));
});
