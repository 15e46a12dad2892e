//! The FIPA message envelope in XML (SC00085), as JADE writes and reads it.

use std::fmt::Write as _;
use std::str::FromStr;

use iw_acl::{AgentId, FipaDateTime};

use crate::Error;

/// The only ACL representation this transport carries: the string form (SC00070).
pub const ACL_REP_STRING: &str = "fipa.acl.rep.string.std";

/// Largest envelope accepted, in bytes.
pub const MAX_ENVELOPE_LEN: usize = 64 * 1024;

/// Deepest XML nesting accepted (an envelope needs 6 levels; resolvers add 3 each).
const MAX_DEPTH: usize = 16;

/// One transport envelope (the first `params` set; JADE sends exactly one).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Envelope {
    /// Final receivers of the message.
    pub to: Vec<AgentId>,
    /// The sending agent.
    pub from: Option<AgentId>,
    /// ACL representation of the payload (`fipa.acl.rep.string.std`).
    pub acl_representation: Option<String>,
    /// Exact length of the payload in bytes.
    pub payload_length: Option<usize>,
    /// Character encoding of the payload; JADE omits it (then US-ASCII/UTF-8 is assumed).
    pub payload_encoding: Option<String>,
    /// When the message was sent; FIPA `20261122T014247645Z` or JADE's `20261122Z014247666`.
    pub date: Option<FipaDateTime>,
    /// Receivers this copy is for (the MTS delivers to these when present, else to `to`).
    pub intended_receiver: Vec<AgentId>,
}

impl Envelope {
    /// The envelope JADE expects for `payload`: to/from/representation/exact length/date/intended
    /// receivers, no `payload-encoding`.
    pub fn for_payload(from: AgentId, to: Vec<AgentId>, payload: &str, date: FipaDateTime) -> Self {
        Self {
            intended_receiver: to.clone(),
            to,
            from: Some(from),
            acl_representation: Some(ACL_REP_STRING.to_owned()),
            payload_length: Some(payload.len()),
            payload_encoding: None,
            date: Some(date),
        }
    }

    /// Receivers to deliver to: the intended receivers, or `to` when there are none.
    pub fn receivers(&self) -> &[AgentId] {
        if self.intended_receiver.is_empty() {
            &self.to
        } else {
            &self.intended_receiver
        }
    }

    /// The XML text, in JADE's layout (prolog on its own line, the rest on one line).
    pub fn to_xml(&self) -> String {
        let mut out = String::from("<?xml version=\"1.0\"?>\n<envelope><params index=\"1\">");
        for aid in &self.to {
            out.push_str("<to>");
            write_aid(&mut out, aid);
            out.push_str("</to>");
        }
        if let Some(from) = &self.from {
            out.push_str("<from>");
            write_aid(&mut out, from);
            out.push_str("</from>");
        }
        write_leaf(
            &mut out,
            "acl-representation",
            self.acl_representation.as_deref(),
        );
        write_leaf(
            &mut out,
            "payload-length",
            self.payload_length.map(|n| n.to_string()).as_deref(),
        );
        write_leaf(
            &mut out,
            "payload-encoding",
            self.payload_encoding.as_deref(),
        );
        write_leaf(
            &mut out,
            "date",
            self.date.map(|d| d.to_string()).as_deref(),
        );
        for aid in &self.intended_receiver {
            out.push_str("<intended-receiver>");
            write_aid(&mut out, aid);
            out.push_str("</intended-receiver>");
        }
        out.push_str("</params></envelope>");
        out
    }

    /// Parses an envelope. Unknown elements are skipped; the first `params` set is used.
    pub fn from_xml(text: &str) -> Result<Self, Error> {
        if text.len() > MAX_ENVELOPE_LEN {
            return Err(Error::TooLarge {
                what: "envelope",
                len: text.len(),
                max: MAX_ENVELOPE_LEN,
            });
        }
        let root = XmlParser { text, pos: 0 }.document()?;
        if root.name != "envelope" {
            return Err(envelope_error(format!(
                "root element is <{}>, expected <envelope>",
                root.name
            )));
        }
        let params = root
            .children
            .iter()
            .find(|c| c.name == "params")
            .ok_or_else(|| envelope_error("no <params> element".to_owned()))?;
        let mut env = Envelope::default();
        for child in &params.children {
            match child.name.as_str() {
                "to" => env.to.extend(aids_in(child)?),
                "from" => env.from = aids_in(child)?.into_iter().next(),
                "intended-receiver" => env.intended_receiver.extend(aids_in(child)?),
                "acl-representation" => env.acl_representation = Some(child.text.trim().to_owned()),
                "payload-encoding" => env.payload_encoding = Some(child.text.trim().to_owned()),
                "payload-length" => {
                    let raw = child.text.trim();
                    let len = raw.parse().map_err(|_| {
                        envelope_error(format!("payload-length {raw:?} is not a byte count"))
                    })?;
                    env.payload_length = Some(len);
                }
                "date" => env.date = Some(parse_envelope_date(child.text.trim())?),
                _ => {}
            }
        }
        Ok(env)
    }
}

/// Parses an envelope date in FIPA form (`20261122T014247645Z`) or JADE's (`20261122Z014247666`,
/// local time, which this platform takes as UTC like a FIPA date without designator).
pub fn parse_envelope_date(raw: &str) -> Result<FipaDateTime, Error> {
    let bytes = raw.as_bytes();
    let jade_form = bytes.len() == 18 && bytes.get(8) == Some(&b'Z');
    let fipa_text = if jade_form {
        format!("{}T{}", &raw[..8], &raw[9..])
    } else {
        raw.to_owned()
    };
    FipaDateTime::from_str(&fipa_text).map_err(|source| Error::Date {
        raw: raw.to_owned(),
        source,
    })
}

fn envelope_error(reason: String) -> Error {
    Error::Envelope { reason }
}

fn write_leaf(out: &mut String, tag: &str, value: Option<&str>) {
    if let Some(value) = value {
        let _ = write!(out, "<{tag}>{}</{tag}>", escape(value));
    }
}

fn write_aid(out: &mut String, aid: &AgentId) {
    out.push_str("<agent-identifier>");
    write_leaf(out, "name", Some(&aid.name));
    if !aid.addresses.is_empty() {
        out.push_str("<addresses>");
        for url in &aid.addresses {
            write_leaf(out, "url", Some(url));
        }
        out.push_str("</addresses>");
    }
    if !aid.resolvers.is_empty() {
        out.push_str("<resolvers>");
        for resolver in &aid.resolvers {
            write_aid(out, resolver);
        }
        out.push_str("</resolvers>");
    }
    out.push_str("</agent-identifier>");
}

fn aids_in(node: &Element) -> Result<Vec<AgentId>, Error> {
    node.children
        .iter()
        .filter(|c| c.name == "agent-identifier")
        .map(aid_from)
        .collect()
}

fn aid_from(node: &Element) -> Result<AgentId, Error> {
    let name = node
        .children
        .iter()
        .find(|c| c.name == "name")
        .map(|c| c.text.trim().to_owned())
        .filter(|n| !n.is_empty())
        .ok_or_else(|| envelope_error("agent-identifier without a <name>".to_owned()))?;
    let mut aid = AgentId::new(name);
    for child in &node.children {
        match child.name.as_str() {
            "addresses" => {
                for url in child.children.iter().filter(|u| u.name == "url") {
                    aid.addresses.push(url.text.trim().to_owned());
                }
            }
            "resolvers" => aid.resolvers.extend(aids_in(child)?),
            _ => {}
        }
    }
    Ok(aid)
}

fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '&' => out.push_str("&amp;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// An XML element: name, child elements, and its own text (entities resolved).
#[derive(Debug, Default)]
struct Element {
    name: String,
    children: Vec<Element>,
    text: String,
}

/// A small XML reader for the envelope subset: elements, attributes (skipped), text, the five
/// predefined entities and numeric references, comments and processing instructions.
struct XmlParser<'a> {
    text: &'a str,
    pos: usize,
}

impl XmlParser<'_> {
    fn err(&self, why: &str) -> Error {
        envelope_error(format!("XML at byte {}: {why}", self.pos))
    }

    fn rest(&self) -> &str {
        self.text.get(self.pos..).unwrap_or("")
    }

    fn skip_misc(&mut self) -> Result<(), Error> {
        loop {
            let skipped = self.rest().len() - self.rest().trim_start().len();
            self.pos += skipped;
            if self.rest().starts_with("<?") {
                self.skip_past("?>")?;
            } else if self.rest().starts_with("<!--") {
                self.skip_past("-->")?;
            } else {
                return Ok(());
            }
        }
    }

    fn skip_past(&mut self, end: &str) -> Result<(), Error> {
        match self.rest().find(end) {
            Some(i) => {
                self.pos += i + end.len();
                Ok(())
            }
            None => Err(self.err(&format!("unterminated construct, no {end:?}"))),
        }
    }

    fn document(mut self) -> Result<Element, Error> {
        self.skip_misc()?;
        let root = self.element(0)?;
        self.skip_misc()?;
        if !self.rest().is_empty() {
            return Err(self.err("content after the root element"));
        }
        Ok(root)
    }

    fn element(&mut self, depth: usize) -> Result<Element, Error> {
        if depth > MAX_DEPTH {
            return Err(self.err("elements nested too deep"));
        }
        if !self.rest().starts_with('<') {
            return Err(self.err("expected '<'"));
        }
        self.pos += 1;
        let name_len = self
            .rest()
            .find(|c: char| c.is_whitespace() || c == '>' || c == '/')
            .ok_or_else(|| self.err("unterminated start tag"))?;
        if name_len == 0 {
            return Err(self.err("empty element name"));
        }
        let name = self.rest()[..name_len].to_owned();
        self.pos += name_len;
        // Attributes are skipped; a '>' inside a quoted value would confuse this, so honour quotes.
        let mut quote = None;
        let mut self_closing = false;
        loop {
            let c = self
                .rest()
                .chars()
                .next()
                .ok_or_else(|| self.err("unterminated start tag"))?;
            self.pos += c.len_utf8();
            match (quote, c) {
                (Some(q), c) if c == q => quote = None,
                (Some(_), _) => {}
                (None, '"' | '\'') => quote = Some(c),
                (None, '/') if self.rest().starts_with('>') => {
                    self.pos += 1;
                    self_closing = true;
                    break;
                }
                (None, '>') => break,
                _ => {}
            }
        }
        let mut node = Element {
            name,
            ..Element::default()
        };
        if self_closing {
            return Ok(node);
        }
        loop {
            let rest = self.rest();
            if rest.starts_with("</") {
                self.pos += 2;
                let end = self
                    .rest()
                    .find('>')
                    .ok_or_else(|| self.err("unterminated end tag"))?;
                let closing = self.rest()[..end].trim();
                if closing != node.name {
                    return Err(self.err(&format!("</{closing}> closes <{}>", node.name)));
                }
                self.pos += end + 1;
                return Ok(node);
            } else if rest.starts_with("<!--") || rest.starts_with("<?") {
                self.skip_misc()?;
            } else if rest.starts_with("<![CDATA[") {
                self.pos += "<![CDATA[".len();
                let end = self
                    .rest()
                    .find("]]>")
                    .ok_or_else(|| self.err("unterminated CDATA"))?;
                node.text.push_str(&self.rest()[..end]);
                self.pos += end + 3;
            } else if rest.starts_with('<') {
                node.children.push(self.element(depth + 1)?);
            } else if rest.is_empty() {
                return Err(self.err(&format!("<{}> is never closed", node.name)));
            } else {
                let end = rest.find('<').unwrap_or(rest.len());
                let raw = &rest[..end];
                unescape_into(raw, &mut node.text).map_err(|why| self.err(&why))?;
                self.pos += end;
            }
        }
    }
}

fn unescape_into(raw: &str, out: &mut String) -> Result<(), String> {
    let mut rest = raw;
    while let Some(amp) = rest.find('&') {
        out.push_str(&rest[..amp]);
        let after = &rest[amp + 1..];
        let semi = after
            .find(';')
            .ok_or_else(|| format!("unterminated entity in {raw:?}"))?;
        let entity = &after[..semi];
        let c = match entity {
            "lt" => '<',
            "gt" => '>',
            "amp" => '&',
            "quot" => '"',
            "apos" => '\'',
            _ => {
                let code = if let Some(hex) = entity.strip_prefix("#x") {
                    u32::from_str_radix(hex, 16).ok()
                } else if let Some(dec) = entity.strip_prefix('#') {
                    dec.parse().ok()
                } else {
                    None
                };
                code.and_then(char::from_u32)
                    .ok_or_else(|| format!("unknown entity &{entity};"))?
            }
        };
        out.push(c);
        rest = &after[semi + 1..];
    }
    out.push_str(rest);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const JADE: &str = "<?xml version=\"1.0\"?>\n<envelope><params index=\"1\"><to><agent-identifier><name>wheelchair1@RustPlatform</name><addresses><url>http://127.0.0.1:9000/acc</url></addresses></agent-identifier></to><from><agent-identifier><name>echo@WheelchairTest</name><addresses><url>http://127.0.0.1:7778/acc</url></addresses></agent-identifier></from><acl-representation>fipa.acl.rep.string.std</acl-representation><payload-length>416</payload-length><date>20261122Z014247666</date><intended-receiver><agent-identifier><name>wheelchair1@RustPlatform</name><addresses><url>http://127.0.0.1:9000/acc</url></addresses></agent-identifier></intended-receiver></params></envelope>";

    #[test]
    fn reads_jade_envelope_with_jade_date() {
        let env = Envelope::from_xml(JADE).unwrap();
        assert_eq!(env.to[0].name, "wheelchair1@RustPlatform");
        assert_eq!(
            env.from.as_ref().unwrap().addresses,
            vec!["http://127.0.0.1:7778/acc"]
        );
        assert_eq!(env.payload_length, Some(416));
        assert_eq!(env.payload_encoding, None);
        let date = env.date.unwrap();
        assert_eq!(
            (date.year, date.hour, date.minute, date.millisecond),
            (2026, 1, 42, 666)
        );
        // Re-encoded it is identical but for the date, which we write in FIPA form.
        assert_eq!(
            env.to_xml(),
            JADE.replace("20261122Z014247666", "20261122T014247666")
        );
    }

    #[test]
    fn fipa_date_form_and_errors() {
        assert_eq!(
            parse_envelope_date("20261122T014247645Z").unwrap().zone,
            Some('Z')
        );
        assert!(parse_envelope_date("2026-11-22").is_err());
        assert!(Envelope::from_xml("<envelope><params><to>").is_err());
        assert!(Envelope::from_xml("<other/>").is_err());
        assert!(
            Envelope::from_xml(
                "<envelope><params><payload-length>x</payload-length></params></envelope>"
            )
            .is_err()
        );
        let deep = "<a>".repeat(100);
        assert!(Envelope::from_xml(&deep).is_err());
    }

    fn aid() -> impl Strategy<Value = AgentId> {
        (
            "[a-z0-9]{1,8}@[A-Za-z]{1,8}",
            proptest::collection::vec("http://[a-z0-9.:<&>\"']{1,12}/acc", 0..3),
        )
            .prop_map(|(n, urls)| {
                urls.into_iter()
                    .fold(AgentId::new(n), AgentId::with_address)
            })
    }

    proptest! {
        #[test]
        fn round_trip(to in proptest::collection::vec(aid(), 1..3), from in aid(),
                      payload in ".{0,40}", ms in 0i64..4_000_000_000_000) {
            let env = Envelope::for_payload(from, to, &payload, FipaDateTime::from_unix_ms(ms));
            prop_assert_eq!(Envelope::from_xml(&env.to_xml()).unwrap(), env);
        }

        #[test]
        fn never_panics(text in ".{0,200}") {
            let _ = Envelope::from_xml(&text);
        }
    }
}
