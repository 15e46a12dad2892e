//! The dashboard over real sockets: the token rule with a plain TCP client, frames and actions
//! over a real websocket, and the size of a 100-chair frame.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

use iw_dashboard::{
    ChairDisplay, ChairView, Dashboard, DashboardConfig, DashboardError, MapView, MessageView,
    PageAction, State,
};

fn get(addr: SocketAddr, target: &str, extra: &str) -> String {
    let port = addr.port();
    let mut stream = TcpStream::connect(("127.0.0.1", port)).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    write!(
        stream,
        "GET {target} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n{extra}\r\n"
    )
    .unwrap();
    let mut reply = String::new();
    stream.read_to_string(&mut reply).expect("read reply");
    reply
}

#[test]
fn a_non_loopback_bind_needs_a_token_and_refuses_requests_without_it() {
    let open = DashboardConfig {
        bind: "0.0.0.0:0".parse().unwrap(),
        token: None,
    };
    assert!(matches!(
        Dashboard::start(open, &MapView::default()),
        Err(DashboardError::TokenRequired { .. })
    ));

    let config = DashboardConfig {
        bind: "0.0.0.0:0".parse().unwrap(),
        token: Some("s3cret".into()),
    };
    let dashboard = Dashboard::start(config, &MapView::default()).expect("start");
    let addr = dashboard.addr();
    assert!(get(addr, "/", "").starts_with("HTTP/1.1 401"));
    assert!(get(addr, "/map.json?token=wrong", "").starts_with("HTTP/1.1 401"));
    assert!(get(addr, "/ws", "").starts_with("HTTP/1.1 401"));
    let page = get(addr, "/?token=s3cret", "");
    assert!(page.starts_with("HTTP/1.1 200"), "{page}");
    assert!(page.contains("<canvas"));
    let map = get(addr, "/map.json", "Authorization: Bearer s3cret\r\n");
    assert!(map.starts_with("HTTP/1.1 200"), "{map}");
    assert!(dashboard.url().ends_with("/?token=s3cret"));
}

#[test]
fn loopback_serves_without_token() {
    let dashboard = Dashboard::start(
        DashboardConfig::default(),
        &MapView {
            name: "b".into(),
            ..MapView::default()
        },
    )
    .expect("start");
    assert!(dashboard.addr().ip().is_loopback());
    let map = get(dashboard.addr(), "/map.json", "");
    assert!(map.starts_with("HTTP/1.1 200"), "{map}");
    assert!(map.contains(r#""name":"b""#));
}

/// A page's websocket.
type Socket = tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<std::net::TcpStream>>;

/// A dashboard on an empty map and one page on its websocket, past the first frame (reads time
/// out after 10 s, so a test cannot hang).
fn page() -> (Dashboard, Socket) {
    let dashboard =
        Dashboard::start(DashboardConfig::default(), &MapView::default()).expect("start");
    let (mut socket, _) =
        tungstenite::connect(format!("ws://{}/ws", dashboard.addr())).expect("websocket");
    #[allow(irrefutable_let_patterns)]
    if let tungstenite::stream::MaybeTlsStream::Plain(s) = socket.get_mut() {
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    }
    let _first = socket.read().expect("first frame");
    (dashboard, socket)
}

/// The first message on `socket` that reports an error (frames before it are skipped).
fn first_error(socket: &mut Socket) -> String {
    loop {
        let text = socket
            .read()
            .expect("reply")
            .into_text()
            .expect("text")
            .to_string();
        if text.contains("error") {
            return text;
        }
    }
}

#[test]
fn frames_go_out_and_actions_come_back_over_the_websocket() {
    let (dashboard, mut socket) = page();
    let state = State {
        t: 1.5,
        chairs: vec![chair(0)],
        ..State::default()
    };
    dashboard.publish(&state).unwrap();
    let frame = loop {
        let text = socket
            .read()
            .expect("frame")
            .into_text()
            .expect("text")
            .to_string();
        let parsed: State = serde_json::from_str(&text).expect("state json");
        if parsed.t == 1.5 {
            break parsed;
        }
    };
    assert_eq!(frame, state);

    socket
        .send(tungstenite::Message::text(
            r#"{"do":"goal","chair":"chair-0","x":3,"y":4}"#,
        ))
        .unwrap();
    socket
        .send(tungstenite::Message::text(r#"{"do":"self-destruct"}"#))
        .unwrap();
    let error = first_error(&mut socket);
    assert!(error.contains("not understood"), "{error}");
    assert_eq!(
        dashboard.try_action(),
        Some(PageAction::Goal {
            chair: "chair-0".into(),
            x: 3.0,
            y: 4.0
        })
    );
    assert_eq!(dashboard.try_action(), None);
}

#[test]
fn a_flood_of_actions_from_one_page_is_cut_to_the_rate_and_the_page_told() {
    let (dashboard, mut socket) = page();
    let started = std::time::Instant::now();
    let sent = 5000;
    for _ in 0..sent {
        socket
            .send(tungstenite::Message::text(r#"{"do":"step"}"#))
            .unwrap();
    }
    let error = first_error(&mut socket);
    assert!(error.contains("too many actions"), "{error}");
    std::thread::sleep(Duration::from_millis(500));
    let mut taken = 0;
    while dashboard.try_action().is_some() {
        taken += 1;
    }
    // Measured after the drain: whatever the server took meanwhile is within this allowance.
    let elapsed = started.elapsed().as_secs_f64();
    let allowed = iw_dashboard::ACTIONS_BURST + iw_dashboard::ACTIONS_PER_S * elapsed;
    assert!(
        (taken as f64) <= allowed + 1.0,
        "{taken} of {sent} actions taken in {elapsed:.2} s; at most {allowed:.0} allowed"
    );
    assert!(taken >= 1, "actions within the rate still pass");
}

fn chair(i: usize) -> ChairView {
    let f = i as f32;
    ChairView {
        n: format!("chair-{i}"),
        k: "virtual".into(),
        p: [12.34 + f, 5.67, -3.1],
        v: [0.55, -0.12],
        s: (0..16)
            .map(|s| {
                if s % 3 == 0 {
                    -1.0
                } else {
                    1.23 + s as f32 / 100.0
                }
            })
            .collect(),
        g: Some([20.5, 7.25]),
        path: (0..20).map(|k| [10.0 + k as f32 * 0.5, 5.25]).collect(),
        u: 0.12,
        c: 3,
        d: ChairDisplay {
            action: "forward 0.55".into(),
            goal: Some("dining-hall".into()),
            warn: true,
            seq: Some((1, 3)),
            answer: Some("agree".into()),
            user: Some([0.6, 0.0]),
            applied: Some([0.2, 0.3]),
        },
    }
}

#[test]
fn a_hundred_chair_frame_stays_small() {
    let state = State {
        t: 123.45,
        chairs: (0..100).map(chair).collect(),
        doors: (0..10).map(|i| (format!("door-{i}"), i % 2 == 0)).collect(),
        msgs: (0..30)
            .map(|i| MessageView {
                from: "cognitive@chair-1".into(),
                to: "control@chair-1".into(),
                act: "request".into(),
                conv: format!("goal-chair-1-{i}"),
                dropped: false,
            })
            .collect(),
        ..State::default()
    };
    let bytes = serde_json::to_string(&state).unwrap().len();
    println!("100-chair frame: {bytes} bytes");
    // 10 Hz x 64 KiB = 640 KiB/s per page at most: smooth on a LAN and on loopback
    assert!(bytes < 64 * 1024, "a 100-chair frame is {bytes} bytes");
}
