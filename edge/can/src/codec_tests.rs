use super::*;

fn id_of(id: Id) -> u32 {
    match id {
        Id::Standard(s) => u32::from(s.as_raw()),
        Id::Extended(e) => e.as_raw(),
    }
}

#[test]
fn ids_of_the_generated_types_match_the_signal_table() {
    assert_eq!(id_of(dbc::BvAccelCmd::MESSAGE_ID), ACCEL_CMD_ID);
    assert_eq!(id_of(dbc::BvSteerCmd::MESSAGE_ID), STEER_CMD_ID);
    assert_eq!(id_of(dbc::BvControlState::MESSAGE_ID), CONTROL_STATE_ID);
    assert_eq!(id_of(dbc::DbwFeedback::MESSAGE_ID), DBW_FEEDBACK_ID);
    assert_eq!(MESSAGE_IDS, [0x110, 0x111, 0x112, 0x120]);
    assert_eq!(dbc::BvAccelCmd::MESSAGE_SIZE, usize::from(FRAME_LEN));
    assert_eq!(dbc::BvAccelCmd::MESSAGE_CYCLE_TIME_MS, 20);
    assert_eq!(dbc::DbwFeedback::MESSAGE_CYCLE_TIME_MS, 10);
}

#[test]
fn known_answer_frames() {
    let mut enc = Encoder::default();
    let f = enc.accel(&AccelCmd { accel_mps2: 1.234, enable: true }).unwrap();
    assert_eq!(f, CanFrame { id: 0x110, len: 8, data: [0xD2, 0x04, 0x01, 0, 0, 0, 0x00, 0x2E] });

    let fb = DbwFeedback { wheel_speed_mps: 12.34, yaw_rate_radps: -0.5, steer_rad: 0.1, mode: 1 };
    for _ in 0..3 {
        enc.feedback(&fb).unwrap();
    }
    let f = enc.feedback(&fb).unwrap();
    assert_eq!(f.data, [0xD2, 0x04, 0x0C, 0xFE, 0xE8, 0x03, 0x31, 0x80]);
}

#[test]
fn decode_returns_what_was_encoded() {
    let mut enc = Encoder::default();
    let mut dec = Decoder::default();
    let msgs = [
        Message::Accel(AccelCmd { accel_mps2: -5.5, enable: true }),
        Message::Steer(SteerCmd { steer_rad: 0.3217, enable: false }),
        Message::Control(ControlState { gate_state: 2, engage_request: true, heartbeat: 200 }),
        Message::Feedback(DbwFeedback { wheel_speed_mps: 21.5, yaw_rate_radps: 0.25, steer_rad: -0.4, mode: 3 }),
    ];
    for m in msgs {
        let f = enc.encode(&m).unwrap();
        assert_eq!(f.id, m.id());
        let back = dec.decode(&f).unwrap();
        match (m, back) {
            (Message::Accel(a), Message::Accel(b)) => {
                assert!((a.accel_mps2 - b.accel_mps2).abs() < 1e-9);
                assert_eq!(a.enable, b.enable);
            }
            (Message::Steer(a), Message::Steer(b)) => {
                assert!((a.steer_rad - b.steer_rad).abs() < 1e-9);
                assert_eq!(a.enable, b.enable);
            }
            (Message::Control(a), Message::Control(b)) => assert_eq!(a, b),
            (Message::Feedback(a), Message::Feedback(b)) => {
                assert!((a.wheel_speed_mps - b.wheel_speed_mps).abs() < 1e-9);
                assert!((a.yaw_rate_radps - b.yaw_rate_radps).abs() < 1e-9);
                assert!((a.steer_rad - b.steer_rad).abs() < 1e-9);
                assert_eq!(a.mode, b.mode);
            }
            other => panic!("decoded another message: {other:?}"),
        }
    }
}

#[test]
fn values_round_to_the_nearest_step() {
    let s = signals::BV_ACCEL_CMD_ACCEL_REQUEST;
    assert_eq!(s.to_raw(1.2346), Ok(1235));
    assert_eq!(s.to_raw(1.2344), Ok(1234));
    assert_eq!(s.to_raw(-1.2346), Ok(-1235));
    assert_eq!(s.to_raw(12.0), Ok(12_000));
    assert_eq!(s.to_physical(12_000), Ok(12.0));
    assert_eq!(s.to_physical(-12_000), Ok(-12.0));
}

#[test]
fn out_of_range_and_non_finite_values_are_rejected_without_using_a_counter() {
    let mut enc = Encoder::default();
    for bad in [12.0001, -12.5, 1e9, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let e = enc.accel(&AccelCmd { accel_mps2: bad, enable: true }).unwrap_err();
        if bad.is_finite() {
            assert!(matches!(e, CodecError::OutOfRange { signal: "BV_AccelCmd.AccelRequest", .. }), "{e}");
        } else {
            assert!(matches!(e, CodecError::NonFinite { .. }), "{e}");
        }
    }
    assert_eq!(enc.next_counter(ACCEL_CMD_ID), Some(0));
    let e = enc.control(&ControlState { gate_state: 4, engage_request: false, heartbeat: 0 }).unwrap_err();
    assert!(matches!(e, CodecError::OutOfRange { signal: "BV_ControlState.GateState", .. }), "{e}");
    let e = enc.feedback(&DbwFeedback { mode: 9, ..DbwFeedback::default() }).unwrap_err();
    assert!(matches!(e, CodecError::OutOfRange { signal: "DBW_Feedback.Mode", .. }), "{e}");
    assert!(enc.steer(&SteerCmd { steer_rad: 1.3, enable: true }).is_err());
    assert_eq!(e.to_string(), "signal DBW_Feedback.Mode: 9 outside [0, 3]");
}

#[test]
fn counters_are_per_id_and_wrap() {
    let mut enc = Encoder::default();
    for i in 0..40u8 {
        let f = enc.accel(&AccelCmd::default()).unwrap();
        assert_eq!(f.data[6] >> 4, i % 16);
        if i % 3 == 0 {
            let s = enc.steer(&SteerCmd::default()).unwrap();
            assert_eq!(s.data[6] >> 4, (i / 3) % 16);
        }
    }
    assert_eq!(enc.next_counter(ACCEL_CMD_ID), Some(40 % 16));
    assert_eq!(enc.next_counter(0x7FF), None);
}

#[test]
fn counter_check_rejects_repeats_and_skips_and_resynchronises() {
    let mut c = CounterCheck::default();
    assert_eq!(c.check(ACCEL_CMD_ID, 5), Ok(()));
    assert_eq!(c.check(ACCEL_CMD_ID, 6), Ok(()));
    assert_eq!(c.check(ACCEL_CMD_ID, 6), Err(CodecError::BadCounter { id: ACCEL_CMD_ID, got: 6, expected: 7 }));
    assert_eq!(c.check(ACCEL_CMD_ID, 7), Ok(()));
    assert_eq!(c.check(ACCEL_CMD_ID, 9), Err(CodecError::BadCounter { id: ACCEL_CMD_ID, got: 9, expected: 8 }));
    assert_eq!(c.check(ACCEL_CMD_ID, 10), Ok(()));
    // Other ids are independent; wrap 15 -> 0.
    assert_eq!(c.check(STEER_CMD_ID, 15), Ok(()));
    assert_eq!(c.check(STEER_CMD_ID, 0), Ok(()));
    assert_eq!(c.check(0x7FF, 0), Err(CodecError::UnknownId { id: 0x7FF }));
    c.reset();
    assert_eq!(c.check(ACCEL_CMD_ID, 3), Ok(()));
}

#[test]
fn decoder_rejects_unknown_ids_lengths_and_checksums() {
    let mut enc = Encoder::default();
    let mut dec = Decoder::default();
    let good = enc.accel(&AccelCmd { accel_mps2: 1.0, enable: true }).unwrap();

    let unknown = CanFrame { id: 0x123, ..good };
    assert_eq!(dec.decode(&unknown), Err(CodecError::UnknownId { id: 0x123 }));
    let extended = CanFrame { id: 0x1000_0110, ..good };
    assert_eq!(dec.decode(&extended), Err(CodecError::UnknownId { id: 0x1000_0110 }));
    let short = CanFrame { len: 7, ..good };
    assert_eq!(dec.decode(&short), Err(CodecError::BadLength { id: 0x110, len: 7, expected: 8 }));
    let mut corrupt = good;
    corrupt.data[0] ^= 0x01;
    assert!(matches!(dec.decode(&corrupt), Err(CodecError::BadChecksum { id: 0x110, .. })));
    // The same payload under another known id fails its checksum (the id seeds the CRC).
    let moved = CanFrame { id: STEER_CMD_ID, ..good };
    assert!(matches!(dec.decode(&moved), Err(CodecError::BadChecksum { .. })));
    // The bad frames did not touch the counter state: the good one still decodes.
    assert!(dec.decode(&good).is_ok());
    // ... but only once.
    assert!(matches!(dec.decode(&good), Err(CodecError::BadCounter { .. })));
}

#[test]
fn decoder_rejects_out_of_range_raw_values_with_a_valid_checksum() {
    // Raw 20000 = 20 m/s², outside [-12, 12], sealed with a correct counter and checksum.
    let mut f = dbc::BvAccelCmd::zeroed().unwrap();
    f.set_accel_request_raw_val(20_000);
    let data = f.seal(0).unwrap();
    let mut dec = Decoder::default();
    let e = dec.decode(&CanFrame::new(ACCEL_CMD_ID, data)).unwrap_err();
    assert!(matches!(e, CodecError::OutOfRange { signal: "BV_AccelCmd.AccelRequest", .. }), "{e}");

    let mut f = dbc::BvControlState::zeroed().unwrap();
    f.set_gate_state_raw_val(7);
    let data = f.seal(0).unwrap();
    let e = dec.decode(&CanFrame::new(CONTROL_STATE_ID, data)).unwrap_err();
    assert!(matches!(e, CodecError::OutOfRange { signal: "BV_ControlState.GateState", .. }), "{e}");
}

#[test]
fn payload_is_the_valid_bytes() {
    let f = CanFrame { id: 1, len: 3, data: [1, 2, 3, 0, 0, 0, 0, 0] };
    assert_eq!(f.payload(), &[1, 2, 3]);
    let g = CanFrame { id: 1, len: 200, data: [0; 8] };
    assert_eq!(g.payload().len(), 8);
}
