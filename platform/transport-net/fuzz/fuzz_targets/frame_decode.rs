//! TCP frame decoding: never panics; whatever decodes re-encodes to the same bytes.
#![no_main]

use iw_transport_net::frame::FrameCodec;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let codec = FrameCodec::new(4096);
    if let Ok(Some((kind, payload, used))) = codec.decode(data) {
        let mut again = Vec::new();
        codec.encode(kind, payload, &mut again).expect("a decoded payload is within the limit");
        assert_eq!(&again[..], &data[..used]);
    }
});
