//! The `H1toKp` homography parser never panics, and an accepted matrix maps points both ways
//! without panicking.
#![no_main]

use iw_features::homography::Homography;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(h) = Homography::parse(text) {
        let _ = h.map(1.0, 2.0);
        let _ = h.map_inverse(3.0, 4.0);
        let _ = h.local_scale(5.0, 6.0);
        let _ = h.with_pixel_origin(1.0).map(0.0, 0.0);
    }
});
