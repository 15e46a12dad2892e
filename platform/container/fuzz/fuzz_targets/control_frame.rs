//! Control frames as they come off the wire: any bytes open to a signed message or are refused
//! with a reason, never a panic.
#![no_main]

use iw_container::Signed;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Err(e) = Signed::open(data) {
        assert!(!e.to_string().is_empty());
    }
});
