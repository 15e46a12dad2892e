//! The transport's errors keep their cause: text that is not UTF-8, a date that does not parse,
//! a root rustls refuses and a failed TLS handshake each hand over the error underneath as
//! `source()`, and the message still ends with it.

use iw_acl::{AclMessage, AgentId, Performative};
use iw_mtp_http::{Error, MtpClient, envelope, tls, wire};
use iw_testdata::cause;
use tokio::io::AsyncWriteExt;
use tokio::net::TcpListener;
use tokio_rustls::rustls;
use tokio_rustls::rustls::pki_types::CertificateDer;

#[test]
fn a_request_head_that_is_not_utf8_keeps_the_decoding_error() {
    let err =
        wire::parse_request_head(b"POST /acc HTTP/1.1\r\nHost: \xff\xfe\r\n\r\n").unwrap_err();
    assert!(
        matches!(
            err,
            Error::Utf8 {
                what: "request head",
                ..
            }
        ),
        "{err}"
    );
    let utf8 = cause::<std::str::Utf8Error>(&err);
    assert_eq!(utf8.valid_up_to(), 26);
}

#[test]
fn an_envelope_date_that_does_not_parse_keeps_the_date_error() {
    let err = envelope::parse_envelope_date("yesterday").unwrap_err();
    assert!(
        matches!(&err, Error::Date { raw, .. } if raw == "yesterday"),
        "{err}"
    );
    cause::<iw_acl::Error>(&err);
}

#[test]
fn a_root_rustls_refuses_keeps_the_rustls_error() {
    let garbage = CertificateDer::from(vec![0x30, 0x03, 0x01, 0x02, 0x03]);
    let err = tls::client_config(&[garbage]).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Tls {
                what: "trusted root",
                ..
            }
        ),
        "{err}"
    );
    cause::<rustls::Error>(&err);
}

#[tokio::test]
async fn a_handshake_with_a_plain_http_server_keeps_the_io_error() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move {
        // answers the ClientHello in clear text, as a plain HTTP server would
        if let Ok((mut stream, _)) = listener.accept().await {
            let _ = stream
                .write_all(&wire::encode_response(400, "Bad Request", true))
                .await;
        }
    });
    let client = MtpClient::with_tls(tls::client_config(&[]).unwrap());
    let message = AclMessage::new(Performative::Inform)
        .with_sender(AgentId::new("a@P"))
        .with_receiver(AgentId::new("b@Q"))
        .with_content("hello");
    let err = client
        .send(
            &format!("https://{addr}/acc"),
            &message,
            vec![AgentId::new("b@Q")],
        )
        .await
        .unwrap_err();
    assert!(
        matches!(&err, Error::Handshake { peer, .. } if *peer == addr.to_string()),
        "{err}"
    );
    cause::<std::io::Error>(&err);
}
