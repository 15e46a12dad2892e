//! `cargo fuzz run drive_action` (from protocols/ontology): any bytes as the action of a request
//! (`((action (agent-identifier :name control@c) BYTES))`, the way a `drive` reaches the control
//! and interface agents) and as a whole content. Reading never panics; a `drive` that reads has
//! finite speeds; whatever reads as a wheelchair content prints as SL that reads back to the
//! same value.
#![no_main]

use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};
use libfuzzer_sys::fuzz_target;

fn check(text: &str) {
    let Ok(content) = WheelchairContent::parse(text) else {
        return;
    };
    if let WheelchairContent::Request {
        action:
            WheelchairAction::Drive {
                linear_mps,
                angular_radps,
            },
        ..
    } = &content
    {
        // SL has no NaN or infinity: a speed that reads is a number
        assert!(
            linear_mps.is_finite() && angular_radps.is_finite(),
            "{text:?} read as a drive that is not finite"
        );
    }
    let printed = content.to_content().to_string();
    let again = WheelchairContent::parse(&printed)
        .unwrap_or_else(|e| panic!("printed {printed:?} of {text:?} does not read back: {e}"));
    assert_eq!(again, content, "round trip of {printed}");
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    check(&format!(
        "((action (agent-identifier :name control@c) {text}))"
    ));
    check(text);
});
