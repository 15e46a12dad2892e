//! Any file bytes: the damage-tolerant reader never panics, returns records in increasing
//! sequence order and damaged regions in file order, inside the file.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // Give most inputs a valid header so the record parser and the resynchronisation run.
    let mut bytes = b"IWLOG\0v2\0\0\0\0\0\0\0\0".to_vec();
    bytes.extend_from_slice(data);
    for input in [data, &bytes[..]] {
        if let Ok(read) = iw_logger::parse_log(input, Path::new("fuzz.iwl"), 1 << 12) {
            assert!(read.records.windows(2).all(|w| w[0].seq < w[1].seq));
            let mut end = 16;
            for d in &read.damage {
                assert!(d.offset >= end && d.offset + d.len <= input.len() as u64);
                end = d.offset + d.len;
            }
        }
    }
});
