//! The real serial driver against the board emulator over a real pseudo-terminal.

use std::time::Duration;

use iw_body::{
    BoardEmulator, Body, BodyError, SerialBody, WheelGeometry, WheelSpeeds, protocol::ProtocolError,
};

const PERIOD_NS: u64 = 50_000_000;

fn connect() -> (BoardEmulator, SerialBody) {
    let board = BoardEmulator::spawn(WheelGeometry::default(), PERIOD_NS).expect("pty pair");
    let body = SerialBody::open(board.port_name(), 115_200, Duration::from_secs(2))
        .expect("open slave tty");
    (board, body)
}

#[test]
fn sonars_and_encoders_arrive_and_speed_references_reach_the_board() {
    let (board, mut body) = connect();
    let handle = board.handle();
    handle.set_sonar(0, Some(0.42));
    handle.set_sonar(15, Some(2.5));
    let first = body.read().unwrap();
    assert_eq!(first.sonar_m[0], Some(0.42));
    assert_eq!(first.sonar_m[15], Some(2.5));
    assert_eq!(first.sonar_m[5], None);
    assert_eq!(first.time_ns, PERIOD_NS);

    body.command(WheelSpeeds {
        left_mps: 0.5,
        right_mps: -0.25,
    })
    .unwrap();
    let mut last = first;
    for _ in 0..20 {
        last = body.read().unwrap();
    }
    // 20 periods of 50 ms: 0.5 m left, -0.25 m right, within one tick
    let g = WheelGeometry::default();
    let left_m = last.left_ticks as f64 * g.m_per_tick();
    let right_m = last.right_ticks as f64 * g.m_per_tick();
    assert!((left_m - 0.5).abs() < 2.0 * g.m_per_tick(), "left {left_m}");
    assert!(
        (right_m + 0.25).abs() < 2.0 * g.m_per_tick(),
        "right {right_m}"
    );
    let state = handle.state();
    assert_eq!(
        state.speeds,
        WheelSpeeds {
            left_mps: 0.5,
            right_mps: -0.25
        }
    );
    body.stop().unwrap();
    body.read().unwrap();
    assert_eq!(handle.state().speeds, WheelSpeeds::STOP);
}

#[test]
fn a_corrupted_frame_is_rejected_with_a_checksum_error_then_reading_recovers() {
    let (board, mut body) = connect();
    board.handle().set_sonar(3, Some(1.0));
    body.read().unwrap();
    board.handle().corrupt_next_reply();
    match body.read() {
        Err(BodyError::Protocol(ProtocolError::Checksum { kind: 0x81, .. })) => {}
        other => panic!("expected a checksum error, got {other:?}"),
    }
    let next = body.read().unwrap();
    assert_eq!(next.sonar_m[3], Some(1.0));
    assert_eq!(next.time_ns, 3 * PERIOD_NS);
}

#[test]
fn out_of_range_speeds_are_refused_before_the_wire() {
    let (board, mut body) = connect();
    assert!(matches!(
        body.command(WheelSpeeds {
            left_mps: f64::NAN,
            right_mps: 0.0
        }),
        Err(BodyError::SpeedOutOfRange { .. })
    ));
    assert!(matches!(
        body.command(WheelSpeeds {
            left_mps: 0.0,
            right_mps: 40.0
        }),
        Err(BodyError::SpeedOutOfRange { .. })
    ));
    body.read().unwrap();
    assert_eq!(board.handle().state().commands, 0);
}

#[test]
fn opening_a_missing_port_names_it() {
    let err = SerialBody::open("/dev/iw-no-such-port", 115_200, Duration::from_millis(100))
        .err()
        .expect("must fail");
    assert!(err.to_string().contains("/dev/iw-no-such-port"), "{err}");
}

/// Polls `f` until it holds; false after `limit` (a bound, not the expected time).
fn eventually(limit: Duration, mut f: impl FnMut() -> bool) -> bool {
    let start = std::time::Instant::now();
    while start.elapsed() < limit {
        if f() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    f()
}

#[test]
fn the_board_watchdog_stops_the_wheels_when_references_stop_arriving() {
    let board = BoardEmulator::spawn_with_watchdog(
        WheelGeometry::default(),
        PERIOD_NS,
        Some(Duration::from_millis(100)),
    )
    .expect("pty pair");
    let mut body = SerialBody::open(board.port_name(), 115_200, Duration::from_secs(2))
        .expect("open slave tty");
    let handle = board.handle();
    let forward = WheelSpeeds {
        left_mps: 0.3,
        right_mps: 0.3,
    };
    body.command(forward).unwrap();
    assert!(
        eventually(Duration::from_secs(10), || handle.state().speeds == forward),
        "the reference reaches the board"
    );
    assert_eq!(handle.state().watchdog_stops, 0);
    // Silence: the driver (e.g. a killed process) sends nothing more.
    assert!(
        eventually(Duration::from_secs(10), || handle.state().speeds
            == WheelSpeeds::STOP),
        "the watchdog zeroes the wheels"
    );
    assert_eq!(handle.state().watchdog_stops, 1);
    body.command(forward).unwrap();
    assert!(
        eventually(Duration::from_secs(10), || handle.state().speeds == forward),
        "a new reference drives again"
    );
}

#[test]
fn a_silent_or_garbled_link_times_out_and_says_which() {
    use serialport::SerialPort;
    use std::io::Write;
    // A bare pty: nothing answers on the master side unless the test writes.
    let (mut master, slave) = serialport::TTYPort::pair().expect("pty pair");
    let mut body = SerialBody::open(
        &slave.name().expect("slave path"),
        115_200,
        Duration::from_millis(100),
    )
    .expect("open slave tty");
    match body.read() {
        Err(
            err @ BodyError::Timeout {
                received: 0,
                skipped: 0,
                ..
            },
        ) => assert!(err.to_string().contains("0 bytes received"), "{err}"),
        other => panic!("expected a silent timeout, got {other:?}"),
    }
    master
        .write_all(&[0x55; 40])
        .and_then(|()| master.flush())
        .expect("line noise");
    match body.read() {
        Err(BodyError::Timeout {
            received: 40,
            skipped,
            ..
        }) => assert!(skipped > 0, "noise must count as skipped"),
        other => panic!("expected a garbled timeout, got {other:?}"),
    }
}

#[test]
fn a_cut_link_is_silent_and_the_board_answers_again_when_it_is_restored() {
    let board = BoardEmulator::spawn(WheelGeometry::default(), PERIOD_NS).expect("pty pair");
    let mut body = SerialBody::open(board.port_name(), 115_200, Duration::from_millis(100))
        .expect("open slave tty");
    let first = body.read().unwrap();
    board.handle().set_silent(true);
    body.command(WheelSpeeds {
        left_mps: 0.5,
        right_mps: 0.5,
    })
    .unwrap();
    match body.read() {
        Err(BodyError::Timeout { received: 0, .. }) => {}
        other => panic!("expected a silent link, got {other:?}"),
    }
    board.handle().set_silent(false);
    let next = body.read().unwrap();
    // the request and the command sent while cut never reached the board
    assert_eq!(next.time_ns, first.time_ns + PERIOD_NS);
    assert_eq!(board.handle().state().commands, 0);
}
