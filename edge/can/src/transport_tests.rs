use socketcan::errors::{CAN_ERR_LOSTARB, CAN_ERR_PROT};
use socketcan::{ExtendedId, Frame};

use super::*;

/// A case: what, the frame, and whether the error is the expected one.
type Case = (&'static str, sc::CanFrame, fn(&CanError) -> bool);

fn error_frame(class: u32, data: &[u8]) -> sc::CanFrame {
    sc::CanFrame::Error(sc::CanErrorFrame::new_error(class, data).unwrap())
}

fn std_id(id: u16) -> StandardId {
    StandardId::new(id).unwrap()
}

#[test]
fn data_frames_convert_both_ways_bit_exact() {
    for len in 0..=8u8 {
        let mut data = [0u8; 8];
        for (i, b) in data.iter_mut().enumerate().take(usize::from(len)) {
            *b = 0xA0 + i as u8;
        }
        let f = CanFrame { id: 0x7FF, len, data };
        let sc_frame = to_socketcan(&f).unwrap();
        assert_eq!(sc_frame.raw_id(), 0x7FF);
        assert_eq!(sc_frame.dlc(), usize::from(len));
        assert_eq!(from_socketcan(sc_frame).unwrap(), Some(f));
    }
}

#[test]
fn frames_outside_the_protocol_are_not_sent() {
    let e = to_socketcan(&CanFrame { id: 0x800, len: 8, data: [0; 8] }).unwrap_err();
    assert!(matches!(e, CanError::Unsupported { id: 0x800, kind: FrameKind::Extended }), "{e}");
    let e = to_socketcan(&CanFrame { id: 0x100, len: 9, data: [0; 8] }).unwrap_err();
    assert!(matches!(e, CanError::Unsupported { kind: FrameKind::TooLong(9), .. }), "{e}");
    assert!(!e.is_bus_fault());
}

#[test]
fn extended_remote_and_fd_frames_are_rejected_on_receive() {
    let ext = sc::CanDataFrame::new(ExtendedId::new(0x110).unwrap(), &[1, 2, 3]).unwrap();
    let e = from_socketcan(sc::CanFrame::Data(ext)).unwrap_err();
    assert!(matches!(e, CanError::Unsupported { id: 0x110, kind: FrameKind::Extended }), "{e}");
    assert_eq!(
        e.to_string(),
        "unsupported CAN frame 0x110: extended (29-bit) identifier; the protocol uses classic data frames with 11-bit ids"
    );

    let rtr = sc::CanRemoteFrame::new_remote(std_id(0x120), 8).unwrap();
    let e = from_socketcan(sc::CanFrame::Remote(rtr)).unwrap_err();
    assert!(matches!(e, CanError::Unsupported { id: 0x120, kind: FrameKind::Remote }), "{e}");

    let fd = sc::CanFdFrame::new(std_id(0x120), &[0u8; 12]).unwrap();
    let e = from_any(sc::CanAnyFrame::Fd(fd)).unwrap_err();
    assert!(matches!(e, CanError::Unsupported { id: 0x120, kind: FrameKind::Fd }), "{e}");
    // Classic frames read through an FD socket are fine.
    let d = sc::CanDataFrame::new(std_id(0x120), &[9; 8]).unwrap();
    assert_eq!(from_any(sc::CanAnyFrame::Normal(d)).unwrap(), Some(CanFrame::new(0x120, [9; 8])));
}

#[test]
fn error_frames_become_typed_errors() {
    let ctrl = |p: ControllerProblems| error_frame(CAN_ERR_CRTL, &[0, p.bits()]);
    let cases: Vec<Case> = vec![
        ("bus-off", error_frame(CAN_ERR_BUSOFF, &[]), |e| matches!(e, CanError::BusOff)),
        ("rx passive", ctrl(ControllerProblems::RX_PASSIVE), |e| matches!(e, CanError::ErrorPassive { .. })),
        ("tx passive", ctrl(ControllerProblems::TX_PASSIVE), |e| matches!(e, CanError::ErrorPassive { .. })),
        ("rx overflow", ctrl(ControllerProblems::RX_OVERFLOW), |e| matches!(e, CanError::Controller { .. })),
        ("warning", ctrl(ControllerProblems::TX_WARNING), |e| matches!(e, CanError::Controller { .. })),
        ("unspecified", ctrl(ControllerProblems::empty()), |e| matches!(e, CanError::Controller { .. })),
        ("protocol", error_frame(CAN_ERR_PROT, &[0, 0, 0x04, 0x08]), |e| matches!(e, CanError::Bus { .. })),
        ("no ack", error_frame(CAN_ERR_ACK, &[]), |e| matches!(e, CanError::Bus { .. })),
        ("tx timeout", error_frame(CAN_ERR_TX_TIMEOUT, &[]), |e| matches!(e, CanError::Bus { .. })),
        ("transceiver", error_frame(CAN_ERR_TRX, &[0, 0, 0, 0, 0x04]), |e| matches!(e, CanError::Bus { .. })),
        ("restarted", error_frame(CAN_ERR_RESTARTED, &[]), |e| matches!(e, CanError::Restarted)),
        (
            "bus-off wins over passive",
            error_frame(CAN_ERR_CRTL | CAN_ERR_BUSOFF, &[0, ControllerProblems::RX_PASSIVE.bits()]),
            |e| matches!(e, CanError::BusOff),
        ),
    ];
    for (what, frame, is_expected) in cases {
        let e = from_socketcan(frame).unwrap_err();
        assert!(is_expected(&e), "{what}: {e}");
        assert!(e.is_bus_fault(), "{what}");
    }
    assert_eq!(from_socketcan(error_frame(CAN_ERR_BUSOFF, &[])).unwrap_err().to_string(), "CAN controller is bus-off");
}

#[test]
fn error_frames_that_report_no_error_are_consumed() {
    assert!(from_socketcan(error_frame(CAN_ERR_LOSTARB, &[5])).unwrap().is_none());
    let active = error_frame(CAN_ERR_CRTL, &[0, ControllerProblems::ACTIVE.bits()]);
    assert!(from_socketcan(active).unwrap().is_none());
}

#[test]
fn the_error_mask_leaves_out_lost_arbitration() {
    assert_eq!(ERROR_MASK & CAN_ERR_LOSTARB, 0);
    assert_ne!(ERROR_MASK & CAN_ERR_BUSOFF, 0);
    assert_ne!(ERROR_MASK & CAN_ERR_CRTL, 0);
}

#[test]
fn opening_a_missing_interface_is_an_open_error() {
    // Here either the kernel has no CAN or the interface does not exist: both are `Open`.
    let e = SocketCanBus::open("v2tnosuchcan0").unwrap_err();
    assert!(matches!(&e, CanError::Open { iface, .. } if iface == "v2tnosuchcan0"), "{e}");
    assert!(e.to_string().starts_with("cannot open CAN interface `v2tnosuchcan0`"), "{e}");
}

#[test]
fn the_transport_trait_is_object_safe() {
    struct Loop(Option<CanFrame>);
    impl CanTransport for Loop {
        fn send(&mut self, frame: &CanFrame) -> Result<(), CanError> {
            self.0 = Some(*frame);
            Ok(())
        }
        fn recv(&mut self, _timeout: Duration) -> Result<Option<CanFrame>, CanError> {
            Ok(self.0.take())
        }
    }
    let mut t: Box<dyn CanTransport> = Box::new(Loop(None));
    t.send(&CanFrame::new(0x110, [1; 8])).unwrap();
    assert_eq!(t.recv(Duration::ZERO).unwrap(), Some(CanFrame::new(0x110, [1; 8])));
    assert_eq!(t.recv(Duration::ZERO).unwrap(), None);
}
