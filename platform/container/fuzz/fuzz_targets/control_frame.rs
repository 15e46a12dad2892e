//! Control datagrams as they come off the wire: any bytes open to a message, are taken as a
//! handshake, or are refused with a reason, never a panic.
#![no_main]

use std::sync::{Arc, LazyLock};

use iw_bus::Time;
use iw_bus::transport::PeerAddr;
use iw_container::ControlChannel;
use iw_layer_security::Identity;
use libfuzzer_sys::fuzz_target;

static IDENTITY: LazyLock<Arc<Identity>> =
    LazyLock::new(|| Arc::new(Identity::generate().expect("identity")));

fuzz_target!(|data: &[u8]| {
    let mut channel = ControlChannel::new(IDENTITY.clone()).expect("channel");
    let mut back = Vec::new();
    if let Err(e) = channel.open(&PeerAddr("fuzz".into()), data, Time(1), &mut back) {
        assert!(!e.to_string().is_empty());
    }
});
