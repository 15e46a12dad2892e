//! Any bytes: the parser must not panic in either escaping, and whatever it accepts must print
//! and parse back to the same message (JADE escaping may refuse only strings ending in `\`).
#![no_main]

use iw_acl::Error;
use iw_acl::codec::{self, Escaping, ParseOptions, PrintOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    for escaping in [Escaping::Standard, Escaping::Jade] {
        let parse_options = if escaping == Escaping::Jade { ParseOptions::jade() } else { ParseOptions::default() };
        let Ok(message) = codec::parse_with(text, &parse_options) else { continue };
        assert_eq!(codec::parse(&codec::print(&message)).as_ref(), Ok(&message));
        match codec::print_with(&message, &PrintOptions::jade()) {
            Ok(printed) => assert_eq!(codec::parse_with(&printed, &ParseOptions::jade()).as_ref(), Ok(&message)),
            Err(err) => assert!(matches!(err, Error::NotRepresentable { .. }), "{err}"),
        }
    }
});
