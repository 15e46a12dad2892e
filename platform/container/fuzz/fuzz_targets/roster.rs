//! Roster files: any bytes parse or are refused naming the file, never a panic, and whatever
//! parses writes back to text that parses to the same roster.
#![no_main]

use iw_container::Roster;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match Roster::parse(text, "fuzz.roster") {
        Ok(roster) => {
            let again = Roster::parse(&roster.to_string(), "fuzz.roster").expect("written back");
            assert_eq!(again, roster);
        }
        Err(e) => assert!(e.to_string().starts_with("roster fuzz.roster")),
    }
});
