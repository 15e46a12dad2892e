//! Data-driven agreement with JADE 4.6.5 on the FIPA vectors in `shared/fipa/vectors/`.

use iw_acl::codec::{self, ParseOptions, PrintOptions};
use iw_acl::{AclMessage, Content, Error};
use serde_json::Value;

mod common;
use common::assert_check_agrees;

fn rows(test: &str, file: &str) -> Option<Vec<Value>> {
    let path = iw_testdata::require(test, &format!("fipa/vectors/{file}"))?;
    let text = std::fs::read_to_string(&path).unwrap();
    Some(
        text.lines()
            .map(|line| serde_json::from_str(line).unwrap())
            .collect(),
    )
}

fn jade_parse(text: &str) -> Result<AclMessage, Error> {
    codec::parse_with(text, &ParseOptions::jade())
}

/// The vectors' JSON shape: byte content by length only.
fn as_vector_json(message: &AclMessage) -> Value {
    let mut json = serde_json::to_value(message).unwrap();
    json.as_object_mut().unwrap().remove("byte_content");
    json
}

/// What JADE's encoder does to a message: content trimmed, empty content dropped.
fn as_jade_sends(message: &AclMessage) -> AclMessage {
    let mut sent = message.clone();
    if let Some(Content::Text(text)) = &message.content {
        let trimmed = text.trim();
        sent.content = (!trimmed.is_empty()).then(|| Content::Text(trimmed.to_owned()));
    }
    sent
}

#[test]
fn decode_rows_agree_with_jade() {
    let Some(rows) = rows("decode_rows_agree_with_jade", "acl-decode.jsonl") else {
        return;
    };
    assert_eq!(rows.len(), 88);
    for row in &rows {
        let source = row["source"].as_str().unwrap();
        let input = row["input"].as_str().unwrap();
        let result = jade_parse(input);
        if row["ok"] == Value::Bool(false) {
            assert!(
                result.is_err(),
                "{source}: JADE refuses it, we accepted {result:?}"
            );
            continue;
        }
        let message =
            result.unwrap_or_else(|err| panic!("{source}: JADE parses it, we fail: {err}"));
        assert_eq!(as_vector_json(&message), row["parsed"], "{source}");
    }
}

#[test]
fn decode_rows_round_trip_in_both_escapings() {
    let Some(rows) = rows(
        "decode_rows_round_trip_in_both_escapings",
        "acl-decode.jsonl",
    ) else {
        return;
    };
    for row in rows.iter().filter(|row| row["ok"] == Value::Bool(true)) {
        let source = row["source"].as_str().unwrap();
        let input = row["input"].as_str().unwrap();
        let message = jade_parse(input).unwrap();
        let jade_text = codec::print_with(&message, &PrintOptions::jade()).unwrap();
        assert_eq!(
            jade_parse(&jade_text).unwrap(),
            message,
            "{source}: {jade_text}"
        );
        assert_eq!(
            codec::parse(&codec::print(&message)).unwrap(),
            message,
            "{source}"
        );
        // JADE's own re-encoding reads back as the same message, up to JADE's content trimming
        // and its dropping of empty user parameters.
        if row["roundtrip_equal"] == Value::Bool(true) {
            let reencoded = jade_parse(row["jade_reencoded"].as_str().unwrap()).unwrap();
            assert_eq!(reencoded, as_jade_sends(&message), "{source}");
        }
    }
}

#[test]
fn encode_rows_read_back_as_jade_reads_its_own() {
    let Some(rows) = rows(
        "encode_rows_read_back_as_jade_reads_its_own",
        "acl-encode.jsonl",
    ) else {
        return;
    };
    assert_eq!(rows.len(), 44);
    for row in &rows {
        let name = row["name"].as_str().unwrap();
        let jade_encoded = row["jade_encoded"].as_str().unwrap();
        let mut json = row["message"].clone();
        if json.get("byte_content_len").is_some() {
            // The vector gives only the length; the bytes are in JADE's encoding.
            let Some(Content::Bytes(bytes)) = jade_parse(jade_encoded).unwrap().content else {
                panic!("{name}")
            };
            json["byte_content"] = base64_of(&bytes).into();
        }
        let message: AclMessage = serde_json::from_value(json).unwrap();
        match codec::print_with(&message, &PrintOptions::jade()) {
            Ok(ours) => {
                assert_eq!(jade_parse(&ours).unwrap(), message, "{name}: {ours}");
                assert_eq!(
                    jade_parse(jade_encoded).unwrap(),
                    as_jade_sends(&message),
                    "{name}"
                );
            }
            Err(Error::NotRepresentable { .. }) => {
                // JADE writes these anyway; what follows the string decides whether it breaks.
                assert!(message.content_text().unwrap().ends_with('\\'), "{name}");
            }
            Err(err) => panic!("{name}: {err}"),
        }
        assert_eq!(
            codec::parse(&codec::print(&message)).unwrap(),
            message,
            "{name}"
        );
    }
}

#[test]
fn non_compliant_platform_output_is_rejected() {
    let Some(path) = iw_testdata::require(
        "non_compliant_platform_output_is_rejected",
        "fipa/vectors/negative-pade-output.txt",
    ) else {
        return;
    };
    let text = std::fs::read_to_string(path).unwrap();
    let err = jade_parse(&text).unwrap_err();
    assert!(
        matches!(err, Error::UnknownParameter { line: 2, .. }),
        "{err}"
    );
    assert!(codec::parse(&text).is_err());
    // Even with the bad parameter name fixed, the unescaped quotes inside the content break it.
    let fixed = text.replace(":conversationID", ":conversation-id");
    let err = jade_parse(&fixed).unwrap_err();
    assert!(err.to_string().contains("kitchen"), "{err}");
}

#[test]
fn wire_payloads_parse() {
    let Some(dir) = iw_testdata::require("wire_payloads_parse", "fipa/wire/acl") else {
        return;
    };
    let mut count = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        let message = jade_parse(&text).unwrap_or_else(|err| panic!("{}: {err}", path.display()));
        assert!(message.sender.is_some(), "{}", path.display());
        count += 1;
    }
    assert!(count >= 7);
}

#[test]
fn jade_replies_captured_on_the_wire_parse() {
    let Some(dir) = iw_testdata::require(
        "jade_replies_captured_on_the_wire_parse",
        "fipa/wire/from-jade",
    ) else {
        return;
    };
    let mut count = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let raw = String::from_utf8(std::fs::read(&path).unwrap()).unwrap();
        // The ACL payload is the last MIME part, ended by CRLF and the closing boundary.
        let payload = raw.rsplit("\r\n\r\n").next().unwrap();
        let payload = &payload[..payload.rfind("\r\n--").unwrap()];
        let message = jade_parse(payload)
            .unwrap_or_else(|err| panic!("{}: {err}\n{payload}", path.display()));
        assert_eq!(
            message.sender.as_ref().unwrap().name.split('@').nth(1),
            Some("WheelchairTest"),
            "{}",
            path.display()
        );
        count += 1;
    }
    assert!(count >= 9);
}

/// `check_with` agrees with `parse_with`, in both escapings, on every text above.
#[test]
fn check_agrees_with_parse_on_every_vector() {
    let mut texts = Vec::new();
    if let Some(rows) = rows(
        "check_agrees_with_parse_on_every_vector",
        "acl-decode.jsonl",
    ) {
        for row in &rows {
            texts.extend(
                ["input", "jade_reencoded"]
                    .iter()
                    .filter_map(|key| row[*key].as_str())
                    .map(str::to_owned),
            );
        }
    }
    if let Some(rows) = rows(
        "check_agrees_with_parse_on_every_vector",
        "acl-encode.jsonl",
    ) {
        texts.extend(
            rows.iter()
                .filter_map(|row| row["jade_encoded"].as_str())
                .map(str::to_owned),
        );
    }
    if let Some(path) = iw_testdata::require(
        "check_agrees_with_parse_on_every_vector",
        "fipa/vectors/negative-pade-output.txt",
    ) {
        texts.push(std::fs::read_to_string(path).unwrap());
    }
    for dir in ["fipa/wire/acl", "fipa/wire/from-jade"] {
        let Some(dir) = iw_testdata::require("check_agrees_with_parse_on_every_vector", dir) else {
            continue;
        };
        for entry in std::fs::read_dir(dir).unwrap() {
            let raw = String::from_utf8(std::fs::read(entry.unwrap().path()).unwrap()).unwrap();
            texts.push(
                raw.rsplit("\r\n\r\n")
                    .next()
                    .unwrap()
                    .split("\r\n--")
                    .next()
                    .unwrap()
                    .to_owned(),
            );
            texts.push(raw);
        }
    }
    for text in &texts {
        assert_check_agrees(text, &ParseOptions::default());
        assert_check_agrees(text, &ParseOptions::jade());
    }
    eprintln!(
        "check_with agreed with parse_with on {} vector texts",
        texts.len()
    );
}

fn base64_of(bytes: &[u8]) -> String {
    use base64::Engine as _;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}
