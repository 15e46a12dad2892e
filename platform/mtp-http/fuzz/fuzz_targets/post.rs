//! Any bytes as an HTTP MTP post or answer: head, multipart body, envelope and ACL must never panic, and
//! an envelope that parses must re-parse to itself after printing.
#![no_main]

use iw_mtp_http::{Envelope, server, wire};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(env) = Envelope::from_xml(text)
    {
        assert_eq!(Envelope::from_xml(&env.to_xml()).ok(), Some(env));
    }
    if let Ok(Some(end)) = wire::find_head_end(data)
        && let Ok(head) = wire::parse_request_head(&data[..end])
    {
        let _ = server::decode(&head, &data[end..]);
    }
    let _ = wire::parse_response_head(data);
});
