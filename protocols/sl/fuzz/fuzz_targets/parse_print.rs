//! `cargo fuzz run parse_print` (from protocols/sl): any bytes, every level; whatever parses
//! must print as SL that parses back to the same tree.
#![no_main]

use iw_sl::{Level, parse};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    for level in Level::ALL {
        if let Ok(content) = parse(text, level) {
            let printed = content.to_string();
            let again = parse(&printed, level).expect("printed SL parses");
            assert_eq!(again, content, "round trip of {printed}");
        }
    }
});
