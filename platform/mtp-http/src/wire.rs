//! HTTP/1.1 framing and the `multipart/mixed` body of a FIPA HTTP MTP post (SC00084).
//!
//! Pure functions over bytes, so the sockets in [`crate::server`] and [`crate::client`] stay thin
//! and the parsers can be fuzzed.

use crate::Error;

/// Largest request head (request line + headers) accepted, in bytes.
pub const MAX_HEAD_LEN: usize = 16 * 1024;
/// Largest request body accepted, in bytes.
pub const MAX_BODY_LEN: usize = 4 * 1024 * 1024;

/// The preamble JADE writes before the first part.
const PREAMBLE: &str = "This is not part of the MIME multipart encoded message.";

/// A parsed request head.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RequestHead {
    /// Request method (`POST`).
    pub method: String,
    /// Request target, origin-form (`/acc`) or absolute-form (`http://127.0.0.1:9000/acc`).
    pub target: String,
    /// `Content-Length`.
    pub content_length: usize,
    /// `Content-Type`, verbatim.
    pub content_type: Option<String>,
    /// Whether the client asked to close the connection after this request.
    pub close: bool,
}

/// Finds the end of a head: the index just past `\r\n\r\n`. A head ended by bare `\n\n` is an
/// error (JADE never answers such a request; we say why instead).
pub fn find_head_end(buf: &[u8]) -> Result<Option<usize>, Error> {
    if let Some(i) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
        return Ok(Some(i + 4));
    }
    if buf.windows(2).any(|w| w == b"\n\n") {
        return Err(Error::Http {
            reason: "request head uses LF-only line endings; FIPA HTTP MTP needs CRLF".into(),
        });
    }
    if buf.len() > MAX_HEAD_LEN {
        return Err(Error::TooLarge {
            what: "request head",
            len: buf.len(),
            max: MAX_HEAD_LEN,
        });
    }
    Ok(None)
}

/// Parses a request head (the bytes up to and including the blank line).
pub fn parse_request_head(head: &[u8]) -> Result<RequestHead, Error> {
    let text = std::str::from_utf8(head).map_err(|source| Error::Utf8 {
        what: "request head",
        source,
    })?;
    let mut lines = text.split("\r\n");
    let request_line = lines.next().unwrap_or("");
    let mut parts = request_line.split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(http_error(format!(
            "malformed request line {request_line:?}"
        )));
    };
    if version != "HTTP/1.1" && version != "HTTP/1.0" {
        return Err(http_error(format!("unsupported HTTP version {version:?}")));
    }
    let mut head = RequestHead {
        method: method.to_owned(),
        target: target.to_owned(),
        content_length: 0,
        content_type: None,
        close: version == "HTTP/1.0",
    };
    let mut saw_length = false;
    for line in lines.filter(|l| !l.is_empty()) {
        let (name, value) = line
            .split_once(':')
            .ok_or_else(|| http_error(format!("header line without ':' {line:?}")))?;
        let value = value.trim();
        match name.trim().to_ascii_lowercase().as_str() {
            "content-length" => {
                head.content_length = value
                    .parse()
                    .map_err(|_| http_error(format!("Content-Length {value:?} is not a number")))?;
                saw_length = true;
            }
            "content-type" => head.content_type = Some(value.to_owned()),
            "connection" => head.close = value.eq_ignore_ascii_case("close"),
            "transfer-encoding" => {
                return Err(http_error(format!(
                    "Transfer-Encoding {value:?} unsupported; send Content-Length"
                )));
            }
            _ => {}
        }
    }
    if !saw_length && head.method == "POST" {
        return Err(http_error("POST without Content-Length".into()));
    }
    if head.content_length > MAX_BODY_LEN {
        return Err(Error::TooLarge {
            what: "request body",
            len: head.content_length,
            max: MAX_BODY_LEN,
        });
    }
    Ok(head)
}

/// The boundary of a `multipart/mixed ; boundary="..."` content type. Like JADE, the boundary
/// must be quoted.
pub fn boundary_of(content_type: &str) -> Result<&str, Error> {
    let mut params = content_type.split(';');
    let media = params.next().unwrap_or("").trim();
    if !media.eq_ignore_ascii_case("multipart/mixed") {
        return Err(Error::Multipart {
            reason: format!("content type {media:?} is not multipart/mixed"),
        });
    }
    for param in params {
        if let Some((key, value)) = param.split_once('=')
            && key.trim().eq_ignore_ascii_case("boundary")
        {
            let value = value.trim();
            return value
                .strip_prefix('"')
                .and_then(|v| v.strip_suffix('"'))
                .filter(|v| !v.is_empty() && v.len() <= 70)
                .ok_or_else(|| Error::Multipart {
                    reason: format!(
                        "boundary {value:?} must be quoted (1..=70 characters), as JADE requires"
                    ),
                });
        }
    }
    Err(Error::Multipart {
        reason: format!("no boundary in {content_type:?}"),
    })
}

/// Splits a multipart body into its envelope (first part) and payload (last part) bodies. The
/// payload must be followed directly by `\r\n--boundary--`.
pub fn split_multipart<'a>(body: &'a [u8], boundary: &str) -> Result<(&'a [u8], &'a [u8]), Error> {
    let delimiter = format!("--{boundary}");
    let delimiter = delimiter.as_bytes();
    let mut parts = Vec::new();
    let mut pos = find(body, delimiter, 0).ok_or_else(|| Error::Multipart {
        reason: "no opening boundary delimiter".into(),
    })?;
    loop {
        let after = pos + delimiter.len();
        let tail = body.get(after..).unwrap_or(&[]);
        if tail.starts_with(b"--") {
            break;
        }
        if !tail.starts_with(b"\r\n") {
            return Err(Error::Multipart {
                reason: format!("boundary delimiter at byte {pos} not followed by CRLF"),
            });
        }
        let part_start = after + 2;
        let next = find(body, &[b"\r\n", delimiter].concat(), part_start).ok_or_else(|| {
            Error::Multipart {
                reason: format!("part at byte {part_start} is never closed by \\r\\n--boundary"),
            }
        })?;
        let part = &body[part_start..next];
        let headers_end = find(part, b"\r\n\r\n", 0)
            .map(|i| i + 4)
            .or_else(|| part.starts_with(b"\r\n").then_some(2))
            .ok_or_else(|| Error::Multipart {
                reason: format!("part at byte {part_start} has no blank line after its headers"),
            })?;
        parts.push(&part[headers_end..]);
        pos = next + 2;
    }
    match (parts.first(), parts.last()) {
        (Some(first), Some(last)) if parts.len() >= 2 => Ok((first, last)),
        _ => Err(Error::Multipart {
            reason: format!("{} part(s); need an envelope and a payload", parts.len()),
        }),
    }
}

fn find(haystack: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    haystack
        .get(from..)?
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|i| i + from)
}

/// A POST of one message in JADE's accepted form: absolute-form target, quoted boundary with a
/// space before `;`, CRLF everywhere, envelope first and ACL payload last.
pub fn encode_request(
    url: &Url,
    envelope_xml: &str,
    payload: &str,
    boundary: &str,
    close: bool,
) -> Vec<u8> {
    let body = format!(
        "{PREAMBLE}\r\n--{boundary}\r\nContent-Type: application/xml\r\n\r\n{envelope_xml}\r\n--{boundary}\r\nContent-Type: application/text\r\n\r\n{payload}\r\n--{boundary}--\r\n"
    );
    let connection = if close { "close" } else { "Keep-Alive" };
    let mut out = format!(
        "POST {url} HTTP/1.1\r\nCache-Control: no-cache\r\nMime-Version: 1.0\r\nHost: {}:{}\r\nContent-Type: multipart/mixed ; boundary=\"{boundary}\"\r\nContent-Length: {}\r\nConnection: {connection}\r\n\r\n",
        url.host,
        url.port,
        body.len()
    )
    .into_bytes();
    out.extend_from_slice(body.as_bytes());
    out
}

/// The answer JADE reads: status line and headers only, `Content-Length: 0`.
pub fn encode_response(status: u16, reason: &str, close: bool) -> Vec<u8> {
    let connection = if close { "close" } else { "keep-alive" };
    format!("HTTP/1.1 {status} {reason}\r\nContent-Length: 0\r\nConnection: {connection}\r\n\r\n")
        .into_bytes()
}

/// A parsed response head.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ResponseHead {
    /// Status code.
    pub status: u16,
    /// `Content-Length`, if given.
    pub content_length: Option<usize>,
    /// Whether the connection cannot carry another request: `Connection: close`, HTTP/1.0, or a
    /// body without a length.
    pub close: bool,
}

/// Parses a response head (status line and headers, up to the blank line).
pub fn parse_response_head(head: &[u8]) -> Result<ResponseHead, Error> {
    let text = String::from_utf8_lossy(head);
    let mut lines = text.split("\r\n");
    let line = lines.next().unwrap_or("");
    let mut parts = line.split(' ');
    let (version, status) = match (parts.next(), parts.next().map(str::parse::<u16>)) {
        (Some(v), Some(Ok(code))) if v.starts_with("HTTP/1.") => (v, code),
        _ => return Err(http_error(format!("malformed status line {line:?}"))),
    };
    let mut response = ResponseHead {
        status,
        content_length: None,
        close: version == "HTTP/1.0",
    };
    for (name, value) in lines.filter_map(|l| l.split_once(':')) {
        let value = value.trim();
        match name.trim().to_ascii_lowercase().as_str() {
            "content-length" => {
                let len = value
                    .parse()
                    .map_err(|_| http_error(format!("Content-Length {value:?} is not a number")))?;
                response.content_length = Some(len);
            }
            "connection" => response.close = value.eq_ignore_ascii_case("close"),
            _ => {}
        }
    }
    if response.content_length.is_none() {
        response.close = true;
    }
    Ok(response)
}

fn http_error(reason: String) -> Error {
    Error::Http { reason }
}

/// An `http://` or `https://` `host:port/path` address of a FIPA platform.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Url {
    /// Whether the address is `https://` (TLS).
    pub secure: bool,
    /// Host name or IP literal.
    pub host: String,
    /// TCP port (80, or 443 for https, when the URL has none).
    pub port: u16,
    /// Path, starting with `/`.
    pub path: String,
}

impl Url {
    /// Parses an `http://` or `https://` URL.
    pub fn parse(text: &str) -> Result<Self, Error> {
        let bad = |why: &str| Error::Address {
            address: text.to_owned(),
            reason: why.to_owned(),
        };
        let (secure, rest) = match (text.strip_prefix("http://"), text.strip_prefix("https://")) {
            (Some(rest), _) => (false, rest),
            (_, Some(rest)) => (true, rest),
            _ => return Err(bad("only http:// and https:// addresses are supported")),
        };
        let (authority, path) = match rest.find('/') {
            Some(i) => (&rest[..i], &rest[i..]),
            None => (rest, "/"),
        };
        let (host, port) = match authority.rsplit_once(':') {
            Some((h, p)) => (h, p.parse().map_err(|_| bad("port is not a number"))?),
            None => (authority, if secure { 443 } else { 80 }),
        };
        if host.is_empty() {
            return Err(bad("no host"));
        }
        Ok(Self {
            secure,
            host: host.to_owned(),
            port,
            path: path.to_owned(),
        })
    }

    /// `host:port`, the key of a connection.
    pub fn authority(&self) -> String {
        format!("{}:{}", self.host, self.port)
    }
}

impl std::fmt::Display for Url {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let scheme = if self.secure { "https" } else { "http" };
        write!(f, "{scheme}://{}:{}{}", self.host, self.port, self.path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn encodes_what_it_parses() {
        let url = Url::parse("http://127.0.0.1:7778/acc").unwrap();
        let bytes = encode_request(&url, "<envelope/>", "(INFORM)", "b0undary", true);
        let end = find_head_end(&bytes).unwrap().unwrap();
        let head = parse_request_head(&bytes[..end]).unwrap();
        assert_eq!(head.target, "http://127.0.0.1:7778/acc");
        assert_eq!(head.content_length, bytes.len() - end);
        let boundary = boundary_of(head.content_type.as_deref().unwrap()).unwrap();
        let (env, payload) = split_multipart(&bytes[end..], boundary).unwrap();
        assert_eq!((env, payload), (&b"<envelope/>"[..], &b"(INFORM)"[..]));
    }

    #[test]
    fn rejects_unquoted_boundary_and_lf_only() {
        assert!(boundary_of("multipart/mixed ; boundary=abc").is_err());
        assert!(find_head_end(b"POST /acc HTTP/1.1\nHost: x\n\nbody").is_err());
        assert!(Url::parse("ftp://x/acc").is_err());
        assert_eq!(Url::parse("https://x/acc").unwrap().port, 443);
        let jade = b"HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nConnection: close\r\n\r\n";
        assert!(parse_response_head(jade).unwrap().close);
        let ours = encode_response(200, "OK", false);
        assert_eq!(
            parse_response_head(&ours).unwrap(),
            ResponseHead {
                status: 200,
                content_length: Some(0),
                close: false
            }
        );
    }

    proptest! {
        #[test]
        fn never_panics(body in proptest::collection::vec(any::<u8>(), 0..300), b in "[a-z]{1,5}") {
            let _ = split_multipart(&body, &b);
            let _ = parse_request_head(&body);
            let _ = find_head_end(&body);
            let _ = parse_response_head(&body);
        }

        #[test]
        fn round_trip(env in "[ -~]{0,60}", payload in "[ -~\n]{0,80}") {
            let url = Url::parse("http://127.0.0.1:9/acc").unwrap();
            let bytes = encode_request(&url, &env, &payload, "7f3a", false);
            let end = find_head_end(&bytes).unwrap().unwrap();
            let (e, p) = split_multipart(&bytes[end..], "7f3a").unwrap();
            prop_assert_eq!(e, env.as_bytes());
            prop_assert_eq!(p, payload.as_bytes());
        }
    }
}
