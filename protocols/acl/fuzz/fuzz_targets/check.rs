//! Any text: `check_with` gives the verdict and the error of `parse_with`, in both escapings, and
//! on success the parsed message's performative, sender name and receiver names.
#![no_main]

use iw_acl::codec::{self, ParseOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    for options in [ParseOptions::default(), ParseOptions::jade()] {
        match (codec::parse_with(text, &options), codec::check_with(text, &options)) {
            (Ok(message), Ok(summary)) => {
                assert_eq!(summary.performative(), message.performative);
                assert_eq!(summary.sender(), message.sender.as_ref().map(|s| s.name.as_str()));
                assert!(summary.receivers().eq(message.receivers.iter().map(|r| r.name.as_str())));
            }
            (Err(parse_err), Err(check_err)) => assert_eq!(check_err, parse_err),
            (parsed, checked) => panic!("disagree on {text:?}: {parsed:?} vs {checked:?}"),
        }
    }
});
