//! The SC00070 writer: one parameter per line, values bare when they are FIPA words.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use base64::Engine as _;

use super::{Escaping, JADE_ENCODING_PARAM, PrintOptions};
use crate::{AclMessage, AgentId, Content, Error};

/// Prints with standard escaping, which can write every message.
pub fn print(message: &AclMessage) -> String {
    let mut out = String::with_capacity(256);
    // Standard escaping represents every string, so writing cannot fail.
    let _ = write_message(message, &mut out, Escaping::Standard);
    out
}

/// Prints with the given options; fails only for strings JADE escaping cannot carry.
pub fn print_with(message: &AclMessage, options: &PrintOptions) -> Result<String, Error> {
    let mut out = String::with_capacity(256);
    write_message(message, &mut out, options.escaping)?;
    Ok(out)
}

/// Appends the message to `out` (reuse one buffer to print many). On error `out` is left as it was.
pub fn print_into(
    message: &AclMessage,
    out: &mut String,
    options: &PrintOptions,
) -> Result<(), Error> {
    let len = out.len();
    write_message(message, out, options.escaping).inspect_err(|_| out.truncate(len))
}

fn write_message(m: &AclMessage, out: &mut String, escaping: Escaping) -> Result<(), Error> {
    out.push('(');
    out.push_str(m.performative.fipa_name());
    if let Some(sender) = &m.sender {
        out.push_str("\n :sender ");
        write_agent_id(sender, out, escaping)?;
    }
    write_agent_set("receiver", &m.receivers, out, escaping)?;
    write_agent_set("reply-to", &m.reply_to, out, escaping)?;
    match &m.content {
        None => {}
        Some(Content::Text(text)) => {
            out.push_str("\n :content ");
            write_quoted("content", text, out, escaping)?;
        }
        Some(Content::Bytes(bytes)) => {
            out.push_str("\n :X-");
            out.push_str(JADE_ENCODING_PARAM);
            out.push_str(" Base64\n :content \"");
            base64::engine::general_purpose::STANDARD.encode_string(bytes, out);
            out.push('"');
        }
    }
    let slots = [
        ("language", &m.language),
        ("encoding", &m.encoding),
        ("ontology", &m.ontology),
        ("protocol", &m.protocol),
        ("conversation-id", &m.conversation_id),
        ("reply-with", &m.reply_with),
        ("in-reply-to", &m.in_reply_to),
    ];
    for (name, value) in slots {
        if let Some(value) = value {
            write_slot(name, value, out, escaping)?;
        }
    }
    if let Some(deadline) = &m.reply_by {
        // A date-time never needs quoting.
        let _ = write!(out, "\n :reply-by {deadline}");
    }
    write_user_params(&m.user_params, ParamsOf::Message, out, escaping)?;
    out.push(')');
    Ok(())
}

fn write_slot(
    name: &'static str,
    value: &str,
    out: &mut String,
    escaping: Escaping,
) -> Result<(), Error> {
    out.push_str("\n :");
    out.push_str(name);
    out.push(' ');
    write_value(name, value, out, escaping)
}

/// Whose user parameters are written.
#[derive(Clone, Copy, PartialEq, Eq)]
enum ParamsOf {
    Message,
    Agent,
}

/// User parameters with their `X-` prefix. A message's byte-content marker (`JADE-Encoding
/// Base64`) is written from the content, never from the map (the parser never leaves it there);
/// in an agent identifier a parameter of that name is an ordinary one, and is written.
fn write_user_params(
    params: &BTreeMap<String, String>,
    of: ParamsOf,
    out: &mut String,
    escaping: Escaping,
) -> Result<(), Error> {
    let lead = match of {
        ParamsOf::Message => "\n :X-",
        ParamsOf::Agent => " :X-",
    };
    for (key, value) in params {
        if of == ParamsOf::Message
            && key == JADE_ENCODING_PARAM
            && value.eq_ignore_ascii_case("Base64")
        {
            continue;
        }
        out.push_str(lead);
        out.push_str(key);
        out.push(' ');
        write_value("user parameter", value, out, escaping)?;
    }
    Ok(())
}

fn write_agent_set(
    name: &str,
    agents: &[AgentId],
    out: &mut String,
    escaping: Escaping,
) -> Result<(), Error> {
    if agents.is_empty() {
        return Ok(());
    }
    out.push_str("\n :");
    out.push_str(name);
    out.push_str(" (set");
    for agent in agents {
        out.push(' ');
        write_agent_id(agent, out, escaping)?;
    }
    out.push(')');
    Ok(())
}

fn write_agent_id(aid: &AgentId, out: &mut String, escaping: Escaping) -> Result<(), Error> {
    out.push_str("(agent-identifier :name ");
    write_value("agent name", &aid.name, out, escaping)?;
    if !aid.addresses.is_empty() {
        out.push_str(" :addresses (sequence");
        for address in &aid.addresses {
            out.push(' ');
            write_value("address", address, out, escaping)?;
        }
        out.push(')');
    }
    if !aid.resolvers.is_empty() {
        out.push_str(" :resolvers (sequence");
        for resolver in &aid.resolvers {
            out.push(' ');
            write_agent_id(resolver, out, escaping)?;
        }
        out.push(')');
    }
    write_user_params(&aid.user_params, ParamsOf::Agent, out, escaping)?;
    out.push(')');
    Ok(())
}

/// A FIPA word: reads back as itself unquoted. Numbers and other words starting with a digit,
/// `#`, `-`, `+`, `@` or `:` are quoted (as JADE does for all but plain numbers).
fn is_word(value: &str) -> bool {
    let bytes = value.as_bytes();
    let Some(&first) = bytes.first() else {
        return false;
    };
    !matches!(first, b'#' | b'0'..=b'9' | b'-' | b'+' | b'@' | b':')
        && bytes
            .iter()
            .all(|&b| b > b' ' && b != 0x7f && !matches!(b, b'(' | b')' | b'"' | b'\\'))
}

fn write_value(
    slot: &'static str,
    value: &str,
    out: &mut String,
    escaping: Escaping,
) -> Result<(), Error> {
    if is_word(value) {
        out.push_str(value);
        Ok(())
    } else {
        write_quoted(slot, value, out, escaping)
    }
}

fn write_quoted(
    slot: &'static str,
    value: &str,
    out: &mut String,
    escaping: Escaping,
) -> Result<(), Error> {
    if escaping == Escaping::Jade && value.ends_with('\\') {
        // The closing quote would read as escaped.
        return Err(Error::NotRepresentable {
            slot,
            value: value.to_owned(),
        });
    }
    out.reserve(value.len() + 2);
    out.push('"');
    let mut plain_from = 0;
    for (i, b) in value.bytes().enumerate() {
        if b == b'"' || (b == b'\\' && escaping == Escaping::Standard) {
            // `i` is at an ASCII byte, so both slices end on character boundaries.
            out.push_str(&value[plain_from..i]);
            out.push('\\');
            plain_from = i;
        }
    }
    out.push_str(&value[plain_from..]);
    out.push('"');
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{ParseOptions, parse, parse_with};
    use crate::{FipaDateTime, Performative};

    fn sample() -> AclMessage {
        AclMessage::new(Performative::Request)
            .with_sender(AgentId::new("a@P").with_address("http://h:1/acc"))
            .with_receiver(
                AgentId::new("b@P").with_resolver(AgentId::new("r").with_user_param("X-k", "v w")),
            )
            .with_content("(move-to :room \"kitchen\") \\ end")
            .with_ontology("two words")
            .with_conversation_id("123")
            .with_reply_by("20991231T235959000Z".parse::<FipaDateTime>().unwrap())
            .with_user_param("battery", "87")
    }

    #[test]
    fn prints_what_parses_back() {
        let m = sample();
        let text = print(&m);
        assert_eq!(parse(&text).unwrap(), m, "{text}");
        assert!(text.starts_with("(REQUEST\n :sender (agent-identifier :name a@P :addresses (sequence http://h:1/acc))"), "{text}");
        assert!(text.contains(":ontology \"two words\""), "{text}");
        assert!(text.ends_with(":X-battery \"87\")"), "{text}");
    }

    #[test]
    fn jade_escaping_round_trips_through_jade_reading() {
        let m =
            AclMessage::new(Performative::Inform).with_content(r#"say "hi" \\" and \\ back\slash"#);
        let text = print_with(&m, &PrintOptions::jade()).unwrap();
        assert!(
            text.contains(r#""say \"hi\" \\\" and \\ back\slash""#),
            "{text}"
        );
        assert_eq!(parse_with(&text, &ParseOptions::jade()).unwrap(), m);
    }

    #[test]
    fn jade_escaping_refuses_what_jade_would_break() {
        for content in ["ends with backslash\\", "\\"] {
            let m = AclMessage::new(Performative::Inform).with_content(content);
            let mut out = String::from("keep");
            let err = print_into(&m, &mut out, &PrintOptions::jade()).unwrap_err();
            assert!(
                matches!(
                    err,
                    Error::NotRepresentable {
                        slot: "content",
                        ..
                    }
                ),
                "{err}"
            );
            assert_eq!(out, "keep");
            assert_eq!(parse(&print(&m)).unwrap(), m);
        }
    }

    #[test]
    fn bytes_travel_as_jade_base64() {
        let m = AclMessage::new(Performative::Inform)
            .with_byte_content(vec![0, 1, 2, 255, b'"', b'\\']);
        let text = print(&m);
        assert_eq!(
            text,
            "(INFORM\n :X-JADE-Encoding Base64\n :content \"AAEC/yJc\")"
        );
        assert_eq!(parse(&text).unwrap(), m);
    }

    #[test]
    fn empty_and_odd_values_are_quoted() {
        for value in ["", "0abc", "-1", ":x", "#h", "a(b)", "tab\there", "é"] {
            let m = AclMessage::new(Performative::Inform).with_ontology(value);
            assert_eq!(parse(&print(&m)).unwrap().ontology.as_deref(), Some(value));
        }
    }
}
