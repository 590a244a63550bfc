#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use super::*;
use crate::traci::{MoveToXy, NewVehicle, VehicleVar};

/// The whole message (header included) of `requests`.
fn message(requests: &[Request<'_>]) -> Vec<u8> {
    let mut buf = Vec::new();
    begin(&mut buf);
    for r in requests {
        encode(&mut buf, r);
    }
    finish(&mut buf).unwrap();
    buf
}

/// A TraCI string: u32 length and bytes.
fn s(text: &str) -> Vec<u8> {
    let mut v = (text.len() as u32).to_be_bytes().to_vec();
    v.extend_from_slice(text.as_bytes());
    v
}

fn with_header(body: &[u8]) -> Vec<u8> {
    let mut v = ((body.len() + 4) as u32).to_be_bytes().to_vec();
    v.extend_from_slice(body);
    v
}

/// A short-form command: length byte, id, content.
fn cmd(id: u8, content: &[u8]) -> Vec<u8> {
    let mut v = vec![(content.len() + 2) as u8, id];
    v.extend_from_slice(content);
    v
}

fn status(id: u8, result: u8, description: &str) -> Vec<u8> {
    let mut content = vec![result];
    content.extend(s(description));
    cmd(id, &content)
}

fn ok(id: u8) -> Vec<u8> {
    status(id, 0x00, "")
}

#[test]
fn control_commands_are_framed_as_the_protocol_says() {
    let mut buf = Vec::new();
    begin(&mut buf);
    encode_version(&mut buf);
    finish(&mut buf).unwrap();
    assert_eq!(buf, [0, 0, 0, 6, 2, 0x00]);

    begin(&mut buf);
    encode_step(&mut buf, 0.0);
    finish(&mut buf).unwrap();
    assert_eq!(buf, [0, 0, 0, 14, 10, 0x02, 0, 0, 0, 0, 0, 0, 0, 0]);

    begin(&mut buf);
    encode_close(&mut buf);
    finish(&mut buf).unwrap();
    assert_eq!(buf, [0, 0, 0, 6, 2, 0x7f]);

    begin(&mut buf);
    encode_load(&mut buf, &["-n".to_owned(), "a.net.xml".to_owned()]);
    finish(&mut buf).unwrap();
    let mut content = vec![0x0e, 0, 0, 0, 2];
    content.extend(s("-n"));
    content.extend(s("a.net.xml"));
    assert_eq!(buf, with_header(&cmd(0x01, &content)));
}

#[test]
fn a_command_over_255_bytes_takes_the_extended_length() {
    let long = "x".repeat(300);
    let mut buf = Vec::new();
    begin(&mut buf);
    encode_load(&mut buf, std::slice::from_ref(&long));
    finish(&mut buf).unwrap();
    // content: list type, count, string (4 + 300)
    let content_len = 1 + 4 + 4 + 300;
    let total = 1 + 4 + 1 + content_len;
    assert_eq!(buf[4], 0);
    assert_eq!(u32::from_be_bytes(buf[5..9].try_into().unwrap()) as usize, total);
    assert_eq!(buf[9], 0x01);
    assert_eq!(buf.len(), 4 + total);
}

#[test]
fn get_commands_carry_variable_and_object() {
    let speed = message(&[Request::Vehicle { vehicle: "v1", var: VehicleVar::Speed }]);
    assert_eq!(speed, [0, 0, 0, 13, 9, 0xa4, 0x40, 0, 0, 0, 2, b'v', b'1']);
    let time = message(&[Request::Time]);
    assert_eq!(time, [0, 0, 0, 11, 7, 0xab, 0x66, 0, 0, 0, 0]);
    let ids = message(&[Request::VehicleIds]);
    assert_eq!(ids, [0, 0, 0, 11, 7, 0xa4, 0x00, 0, 0, 0, 0]);
    let vars = [
        (VehicleVar::Position, 0x42),
        (VehicleVar::Angle, 0x43),
        (VehicleVar::Acceleration, 0x72),
        (VehicleVar::LaneId, 0x51),
        (VehicleVar::RoadId, 0x50),
        (VehicleVar::LanePosition, 0x56),
    ];
    for (var, id) in vars {
        assert_eq!(message(&[Request::Vehicle { vehicle: "", var }])[6], id, "{var:?}");
    }
}

#[test]
fn set_commands_carry_typed_values() {
    let speed = message(&[Request::SetSpeed { vehicle: "v", mps: 10.0 }]);
    let mut content = vec![0x40];
    content.extend(s("v"));
    content.push(0x0b);
    content.extend(10.0f64.to_be_bytes());
    assert_eq!(speed, with_header(&cmd(0xc4, &content)));

    let max = message(&[Request::SetMaxSpeed { vehicle: "v", mps: 10.0 }]);
    let mut content = vec![0x41];
    content.extend(s("v"));
    content.push(0x0b);
    content.extend(10.0f64.to_be_bytes());
    assert_eq!(max, with_header(&cmd(0xc4, &content)));

    for (req, var) in [
        (Request::SetSpeedMode { vehicle: "v", mode: 31 }, 0xb3),
        (Request::SetLaneChangeMode { vehicle: "v", mode: 1621 }, 0xb6),
    ] {
        let mode = match req {
            Request::SetSpeedMode { mode, .. } | Request::SetLaneChangeMode { mode, .. } => mode,
            _ => unreachable!(),
        };
        let mut content = vec![var];
        content.extend(s("v"));
        content.push(0x09);
        content.extend(mode.to_be_bytes());
        assert_eq!(message(&[req]), with_header(&cmd(0xc4, &content)));
    }

    let edges = ["a".to_owned(), "bc".to_owned()];
    let route = message(&[Request::AddRoute { id: "r", edges: &edges }]);
    let mut content = vec![0x80];
    content.extend(s("r"));
    content.extend([0x0e, 0, 0, 0, 2]);
    content.extend(s("a"));
    content.extend(s("bc"));
    assert_eq!(route, with_header(&cmd(0xc6, &content)));
}

#[test]
fn move_to_xy_is_a_compound_of_six() {
    let m = MoveToXy { vehicle: "bv", edge: "e", lane: 1, x: 1.5, y: -2.0, angle_deg: 90.0, keep_route: 2 };
    let mut content = vec![0xb4];
    content.extend(s("bv"));
    content.extend([0x0f, 0, 0, 0, 6, 0x0c]);
    content.extend(s("e"));
    content.extend([0x09, 0, 0, 0, 1, 0x0b]);
    content.extend(1.5f64.to_be_bytes());
    content.push(0x0b);
    content.extend((-2.0f64).to_be_bytes());
    content.push(0x0b);
    content.extend(90.0f64.to_be_bytes());
    content.extend([0x08, 2]);
    assert_eq!(content.len() + 2, 54);
    assert_eq!(message(&[Request::MoveToXy(m)]), with_header(&cmd(0xc4, &content)));
}

#[test]
fn add_full_is_a_compound_of_twelve_strings_and_two_integers() {
    let v = NewVehicle {
        id: "vut",
        route: "r",
        vehicle_type: "DEFAULT_VEHTYPE",
        depart: "now",
        depart_lane: "1",
        depart_pos: "base",
        depart_speed: "0",
        arrival_pos: "max",
    };
    let mut content = vec![0x85];
    content.extend(s("vut"));
    content.extend([0x0f, 0, 0, 0, 14]);
    let strings = ["r", "DEFAULT_VEHTYPE", "now", "1", "base", "0", "current", "max", "current", "", "", ""];
    for text in strings {
        content.push(0x0c);
        content.extend(s(text));
    }
    content.extend([0x09, 0, 0, 0, 0, 0x09, 0, 0, 0, 0]);
    assert_eq!(message(&[Request::AddVehicle(v)]), with_header(&cmd(0xc4, &content)));
}

#[test]
fn replies_decode_in_request_order() {
    let requests = [
        Request::SetSpeed { vehicle: "v", mps: 3.0 },
        Request::Vehicle { vehicle: "v", var: VehicleVar::Speed },
        Request::Vehicle { vehicle: "v", var: VehicleVar::Position },
        Request::Vehicle { vehicle: "v", var: VehicleVar::LaneId },
        Request::VehicleIds,
    ];
    let mut body = ok(0xc4);
    body.extend(ok(0xa4));
    let mut speed = vec![0x40];
    speed.extend(s("v"));
    speed.push(0x0b);
    speed.extend(3.0f64.to_be_bytes());
    body.extend(cmd(0xb4, &speed));
    body.extend(ok(0xa4));
    let mut pos = vec![0x42];
    pos.extend(s("v"));
    pos.push(0x01);
    pos.extend(1.0f64.to_be_bytes());
    pos.extend((-2.5f64).to_be_bytes());
    body.extend(cmd(0xb4, &pos));
    body.extend(ok(0xa4));
    let mut lane = vec![0x51];
    lane.extend(s("v"));
    lane.push(0x0c);
    lane.extend(s("2_1"));
    body.extend(cmd(0xb4, &lane));
    body.extend(ok(0xa4));
    let mut ids = vec![0x00];
    ids.extend(s(""));
    ids.extend([0x0e, 0, 0, 0, 2]);
    ids.extend(s("a"));
    ids.extend(s("v"));
    body.extend(cmd(0xb4, &ids));

    let mut out = Vec::new();
    decode_replies(&body, &requests, &mut out).unwrap();
    assert_eq!(
        out,
        [
            Reply::Done,
            Reply::Number(3.0),
            Reply::Position([1.0, -2.5]),
            Reply::Text("2_1".to_owned()),
            Reply::Texts(vec!["a".to_owned(), "v".to_owned()]),
        ]
    );

    // Every proper prefix is a protocol error, never a panic.
    for cut in 0..body.len() {
        let err = decode_replies(&body[..cut], &requests, &mut out).unwrap_err();
        assert!(matches!(err, SumoError::Protocol { .. }), "cut {cut}: {err}");
    }
    // A trailing byte is one too.
    body.push(0);
    assert!(matches!(
        decode_replies(&body, &requests, &mut out),
        Err(SumoError::Protocol { field: "message length", .. })
    ));
}

#[test]
fn an_error_status_names_the_command_and_sumos_message() {
    let body = status(0xc4, 0xff, "Vehicle 'x' is not known.");
    let err = decode_replies(&body, &[Request::SetSpeed { vehicle: "x", mps: 1.0 }], &mut Vec::new()).unwrap_err();
    match err {
        SumoError::Command { command, message } => {
            assert_eq!(command, "vehicle.setSpeed('x', 1)");
            assert_eq!(message, "Vehicle 'x' is not known.");
        }
        other => panic!("{other}"),
    }
}

#[test]
fn wrong_ids_and_types_are_protocol_errors() {
    let req = [Request::Vehicle { vehicle: "v", var: VehicleVar::Speed }];
    let reply = |resp_id: u8, var: u8, object: &str, ty: u8| {
        let mut body = ok(0xa4);
        let mut content = vec![var];
        content.extend(s(object));
        content.push(ty);
        content.extend(1.0f64.to_be_bytes());
        body.extend(cmd(resp_id, &content));
        body
    };
    let mut out = Vec::new();
    assert!(decode_replies(&reply(0xb4, 0x40, "v", 0x0b), &req, &mut out).is_ok());
    let cases = [
        (reply(0xb5, 0x40, "v", 0x0b), "response command id"),
        (reply(0xb4, 0x41, "v", 0x0b), "response variable"),
        (reply(0xb4, 0x40, "w", 0x0b), "response object id"),
        (reply(0xb4, 0x40, "v", 0x0c), "response value type"),
        (ok(0xc4), "status command id"),
        (status(0xa4, 0x07, ""), "status result"),
    ];
    for (body, want) in cases {
        match decode_replies(&body, &req, &mut out) {
            Err(SumoError::Protocol { field, .. }) => assert_eq!(field, want),
            other => panic!("{want}: {other:?}"),
        }
    }
}

#[test]
fn lengths_are_checked_before_anything_is_allocated() {
    assert_eq!(body_len([0, 0, 0, 4]).unwrap(), 0);
    assert_eq!(body_len([0, 0, 1, 0]).unwrap(), 252);
    for bad in [[0, 0, 0, 3], [0xff, 0xff, 0xff, 0xff], [0x04, 0, 0, 1]] {
        assert!(matches!(body_len(bad), Err(SumoError::Protocol { field: "message length", .. })));
    }
    // A string claiming 2 GiB in a 20-byte message.
    let mut body = ok(0xa4);
    body.extend([0, 0, 0, 0, 11, 0xb4, 0x51, 0x7f, 0xff, 0xff, 0xff]);
    let req = [Request::Vehicle { vehicle: "v", var: VehicleVar::LaneId }];
    assert!(matches!(decode_replies(&body, &req, &mut Vec::new()), Err(SumoError::Protocol { .. })));
    // A list claiming a negative count.
    let mut body = ok(0xa4);
    let mut ids = vec![0x00];
    ids.extend(s(""));
    ids.extend([0x0e, 0xff, 0xff, 0xff, 0xff]);
    body.extend(cmd(0xb4, &ids));
    let err = decode_replies(&body, &[Request::VehicleIds], &mut Vec::new()).unwrap_err();
    assert!(matches!(err, SumoError::Protocol { field: "string list count", .. }), "{err}");
}

#[test]
fn version_step_and_status_replies_decode() {
    let mut body = ok(0x00);
    let mut content = 22i32.to_be_bytes().to_vec();
    content.extend(s("SUMO v1_28_0"));
    body.extend(cmd(0x00, &content));
    assert_eq!(decode_version(&body).unwrap(), (22, "SUMO v1_28_0".to_owned()));

    let mut step = ok(0x02);
    step.extend(0i32.to_be_bytes());
    decode_step(&step).unwrap();
    assert!(matches!(decode_step(&ok(0x02)), Err(SumoError::Protocol { .. })));

    decode_status(&ok(0x7f), 0x7f, "close()").unwrap();
    let refused = status(0x01, 0xff, "bad option");
    assert!(matches!(
        decode_status(&refused, 0x01, "load()"),
        Err(SumoError::Command { message, .. }) if message == "bad option"
    ));
}

#[test]
fn random_bytes_never_panic_the_decoder() {
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let requests = [
        Request::Vehicle { vehicle: "v", var: VehicleVar::Position },
        Request::VehicleIds,
        Request::SetSpeed { vehicle: "v", mps: 1.0 },
    ];
    let mut out = Vec::new();
    for round in 0..20_000 {
        let len = (next() % 96) as usize;
        let mut body: Vec<u8> = (0..len).map(|_| next() as u8).collect();
        // Half the time, start with a plausible status so the decoder gets further.
        if round % 2 == 0 {
            let mut head = ok([0xa4, 0xc4, 0x00, 0x02][round / 2 % 4]);
            head.append(&mut body);
            body = head;
        }
        let _ = decode_replies(&body, &requests, &mut out);
        let _ = decode_version(&body);
        let _ = decode_step(&body);
        let _ = decode_status(&body, 0x7f, "close()");
    }
}
