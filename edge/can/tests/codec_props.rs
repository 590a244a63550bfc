//! Property tests of the DBC codec: every message round-trips bit-exact for random in-range
//! values, out-of-range and non-finite values are rejected, counters wrap and are supervised,
//! the checksum detects every single-bit flip, and no frame makes the decoder panic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)] // test code

use proptest::prelude::*;
use v2t_can::checksum::frame_checksum;
use v2t_can::codec::{
    AccelCmd, CanFrame, CodecError, ControlState, DbwFeedback, Decoder, Encoder, MESSAGE_IDS, Message, Scale, SteerCmd,
    signals,
};

fn in_range(s: Scale) -> impl Strategy<Value = f64> {
    s.min..=s.max
}

fn small_int(s: Scale) -> impl Strategy<Value = u8> {
    (s.min as u8)..=(s.max as u8)
}

fn any_message() -> impl Strategy<Value = Message> {
    prop_oneof![
        (in_range(signals::BV_ACCEL_CMD_ACCEL_REQUEST), any::<bool>())
            .prop_map(|(accel_mps2, enable)| Message::Accel(AccelCmd { accel_mps2, enable })),
        (in_range(signals::BV_STEER_CMD_STEER_REQUEST), any::<bool>())
            .prop_map(|(steer_rad, enable)| Message::Steer(SteerCmd { steer_rad, enable })),
        (small_int(signals::BV_CONTROL_STATE_GATE_STATE), any::<bool>(), any::<u8>()).prop_map(
            |(gate_state, engage_request, heartbeat)| Message::Control(ControlState {
                gate_state,
                engage_request,
                heartbeat
            })
        ),
        (
            in_range(signals::DBW_FEEDBACK_WHEEL_SPEED),
            in_range(signals::DBW_FEEDBACK_YAW_RATE),
            in_range(signals::DBW_FEEDBACK_STEER_ANGLE),
            small_int(signals::DBW_FEEDBACK_MODE),
        )
            .prop_map(|(wheel_speed_mps, yaw_rate_radps, steer_rad, mode)| {
                Message::Feedback(DbwFeedback { wheel_speed_mps, yaw_rate_radps, steer_rad, mode })
            }),
    ]
}

/// The physical signals of a message with their scales.
fn physical(m: &Message) -> Vec<(f64, Scale)> {
    match m {
        Message::Accel(a) => vec![(a.accel_mps2, signals::BV_ACCEL_CMD_ACCEL_REQUEST)],
        Message::Steer(s) => vec![(s.steer_rad, signals::BV_STEER_CMD_STEER_REQUEST)],
        Message::Control(_) => vec![],
        Message::Feedback(f) => vec![
            (f.wheel_speed_mps, signals::DBW_FEEDBACK_WHEEL_SPEED),
            (f.yaw_rate_radps, signals::DBW_FEEDBACK_YAW_RATE),
            (f.steer_rad, signals::DBW_FEEDBACK_STEER_ANGLE),
        ],
    }
}

/// `m` with its (first) physical signal replaced by `x`.
fn with_value(m: &Message, x: f64) -> Message {
    match *m {
        Message::Accel(a) => Message::Accel(AccelCmd { accel_mps2: x, ..a }),
        Message::Steer(s) => Message::Steer(SteerCmd { steer_rad: x, ..s }),
        Message::Control(c) => Message::Control(c),
        Message::Feedback(f) => Message::Feedback(DbwFeedback { wheel_speed_mps: x, ..f }),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn every_message_round_trips_bit_exact(m in any_message(), skip in 0u8..16) {
        let (mut first, mut second) = (Encoder::default(), Encoder::default());
        // Start both encoders at the same, arbitrary counter.
        for _ in 0..skip {
            first.encode(&m).unwrap();
            second.encode(&m).unwrap();
        }
        let frame = first.encode(&m).unwrap();
        prop_assert_eq!(frame.id, m.id());
        prop_assert_eq!(frame.len, 8);
        let decoded = Decoder::default().decode(&frame).unwrap();
        let again = second.encode(&decoded).unwrap();
        prop_assert_eq!(frame, again);
        // The decoded value is the original rounded to the signal's step.
        for ((orig, scale), (dec, _)) in physical(&m).into_iter().zip(physical(&decoded)) {
            prop_assert!((orig - dec).abs() <= scale.factor / 2.0 + 1e-12, "{} {} {}", scale.name, orig, dec);
        }
        if let (Message::Control(a), Message::Control(b)) = (m, decoded) {
            prop_assert_eq!(a, b);
        }
    }

    #[test]
    fn out_of_range_and_non_finite_values_are_rejected(m in any_message(), beyond in 1e-6f64..1e6, above in any::<bool>()) {
        if let Some(&(_, scale)) = physical(&m).first() {
            let x = if above { scale.max + beyond.max(scale.factor) } else { scale.min - beyond.max(scale.factor) };
            let mut enc = Encoder::default();
            let e = enc.encode(&with_value(&m, x)).unwrap_err();
            prop_assert!(matches!(e, CodecError::OutOfRange { .. }), "{}", e);
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let e = enc.encode(&with_value(&m, bad)).unwrap_err();
                prop_assert!(matches!(e, CodecError::NonFinite { .. }), "{}", e);
            }
            // Rejected messages use no counter.
            prop_assert_eq!(enc.next_counter(m.id()), Some(0));
        }
    }

    #[test]
    fn every_single_bit_flip_is_detected(m in any_message(), skip in 0u8..16) {
        let mut enc = Encoder::default();
        for _ in 0..skip {
            enc.encode(&m).unwrap();
        }
        let frame = enc.encode(&m).unwrap();
        for bit in 0..64 {
            let mut bad = frame;
            bad.data[bit / 8] ^= 1 << (bit % 8);
            let e = Decoder::default().decode(&bad).unwrap_err();
            prop_assert!(matches!(e, CodecError::BadChecksum { .. }), "bit {}: {}", bit, e);
        }
    }

    #[test]
    fn counters_wrap_and_a_lost_frame_is_caught(m in any_message(), n in 17usize..60, lost in 1usize..16) {
        let mut enc = Encoder::default();
        let mut dec = Decoder::default();
        for _ in 0..n {
            let f = enc.encode(&m).unwrap();
            prop_assert!(dec.decode(&f).is_ok());
        }
        // Drop `lost` frames: the next one has a skipped counter and is rejected, the one after
        // is accepted again (the check resynchronises).
        for _ in 0..lost {
            enc.encode(&m).unwrap();
        }
        let f = enc.encode(&m).unwrap();
        let e = dec.decode(&f).unwrap_err();
        prop_assert!(matches!(e, CodecError::BadCounter { .. }), "{}", e);
        let f = enc.encode(&m).unwrap();
        prop_assert!(dec.decode(&f).is_ok());
        // A replayed frame is rejected.
        let e = dec.decode(&f).unwrap_err();
        prop_assert!(matches!(e, CodecError::BadCounter { .. }), "{}", e);
    }

    #[test]
    fn no_frame_makes_the_decoder_panic(id in prop_oneof![
        3 => prop::sample::select(MESSAGE_IDS.to_vec()),
        1 => any::<u32>(),
    ], len in 0u8..=16, data in any::<[u8; 8]>(), seal in any::<bool>()) {
        let mut data = data;
        if seal {
            data[7] = frame_checksum(id, &data);
        }
        let frame = CanFrame { id, len, data };
        let mut dec = Decoder::default();
        if let Ok(m) = dec.decode(&frame) {
            // Whatever is accepted is a valid message that encodes again.
            prop_assert_eq!(m.id(), id);
            prop_assert!(Encoder::default().encode(&m).is_ok());
        }
    }
}
