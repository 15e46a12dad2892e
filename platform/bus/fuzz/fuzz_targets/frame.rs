//! Bus frames: decoding any bytes never panics, and whatever decodes re-encodes to a frame that
//! decodes to the same envelope.
#![no_main]

use iw_bus::FrameCodec;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let codec = FrameCodec::new();
    if let Ok(Some((env, used))) = codec.decode(data) {
        assert!(used <= data.len());
        let frame = codec.encode_to_vec(&env).expect("a decoded envelope encodes");
        assert_eq!(frame.as_slice(), &data[..used], "canonical encoding");
        assert_eq!(codec.decode_datagram(&frame).expect("round trip"), env);
    }
});
