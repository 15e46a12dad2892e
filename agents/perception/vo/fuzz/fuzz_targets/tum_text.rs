//! TUM text parsers never panic, and a parsed trajectory survives write + parse.
#![no_main]

use std::path::Path;

use iw_vo::tum;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let path = Path::new("fuzz.txt");
    let _ = tum::parse_list(path, text);
    let _ = tum::parse_associations(path, text);
    if let Ok(poses) = tum::parse_trajectory(path, text) {
        let mut out = Vec::new();
        tum::write_trajectory(&mut out, &poses).expect("writing to memory");
        let again = tum::parse_trajectory(path, std::str::from_utf8(&out).expect("own output is UTF-8"))
            .expect("own output parses");
        assert_eq!(again.len(), poses.len());
    }
});
