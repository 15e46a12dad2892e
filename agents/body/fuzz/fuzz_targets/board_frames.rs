//! Any byte stream on the serial line: the decoder never panics, always terminates, and every
//! frame it accepts re-encodes to bytes that decode to the same frame.
#![no_main]

use iw_body::protocol::{Decoder, encode};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let mut decoder = Decoder::new();
    decoder.push(bytes);
    // each call consumes at least the two sync bytes or returns Ok(None)
    for _ in 0..=bytes.len() {
        match decoder.decode() {
            Ok(None) => break,
            Ok(Some(message)) => {
                let mut again = Decoder::new();
                again.push(&encode(&message));
                assert_eq!(again.decode().ok().flatten().as_ref(), Some(&message));
            }
            Err(_) => {}
        }
    }
});
