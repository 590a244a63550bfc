//! Frame protection of `config/can/bv.dbc`: the 8-bit checksum in byte 7 and the 4-bit rolling
//! counter in byte 6 (bits 4..7) of every frame.
//!
//! Checksum: CRC-8/SAE-J1850 — polynomial `0x1D`, initial value `0xFF`, no reflection, final XOR
//! `0xFF` (check value `0x4B` for ASCII `123456789`) — over nine bytes: the 11-bit message id as
//! two bytes little-endian (`id & 0xFF`, `id >> 8`), then data bytes 0..6. Seeding with the id
//! makes a frame that arrives under another id fail its checksum, not just decode as garbage.

/// Generator polynomial of CRC-8/SAE-J1850 (x⁸ + x⁴ + x³ + x² + 1, top bit implied).
pub const CRC8_J1850_POLY: u8 = 0x1D;
/// Initial value of the CRC register.
pub const CRC8_J1850_INIT: u8 = 0xFF;
/// Final XOR.
pub const CRC8_J1850_XOROUT: u8 = 0xFF;

/// Feeds `bytes` into a CRC-8/SAE-J1850 register (no final XOR).
fn crc8_update(mut crc: u8, bytes: &[u8]) -> u8 {
    for &b in bytes {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 { (crc << 1) ^ CRC8_J1850_POLY } else { crc << 1 };
        }
    }
    crc
}

/// CRC-8/SAE-J1850 of `bytes`.
pub fn crc8_j1850(bytes: &[u8]) -> u8 {
    crc8_update(CRC8_J1850_INIT, bytes) ^ CRC8_J1850_XOROUT
}

/// The checksum byte of a frame with id `id` and payload `data` (byte 7 itself is not covered).
pub fn frame_checksum(id: u32, data: &[u8; 8]) -> u8 {
    let [lo, hi, ..] = id.to_le_bytes();
    let [d0, d1, d2, d3, d4, d5, d6, _] = *data;
    crc8_j1850(&[lo, hi, d0, d1, d2, d3, d4, d5, d6])
}

/// Byte index of the checksum.
pub const CHECKSUM_BYTE: usize = 7;
/// Number of distinct counter values (4 bits).
pub const COUNTER_MODULUS: u8 = 16;

/// The counter that follows `counter`.
pub fn next_counter(counter: u8) -> u8 {
    (counter.wrapping_add(1)) % COUNTER_MODULUS
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_answers_of_crc8_sae_j1850() {
        // The catalogue check value of CRC-8/SAE-J1850.
        assert_eq!(crc8_j1850(b"123456789"), 0x4B);
        // Empty input: init 0xFF xor-out 0xFF.
        assert_eq!(crc8_j1850(&[]), 0x00);
        // Single bytes (values from an independent bitwise implementation).
        assert_eq!(crc8_j1850(&[0x00]), 0x3B);
        assert_eq!(crc8_j1850(&[0xFF]), 0xFF);
    }

    #[test]
    fn frame_checksum_covers_the_id_and_seven_bytes() {
        let data = [1, 2, 3, 4, 5, 6, 7, 0xAA];
        let c = frame_checksum(0x110, &data);
        assert_eq!(c, crc8_j1850(&[0x10, 0x01, 1, 2, 3, 4, 5, 6, 7]));
        // Byte 7 is not covered.
        let mut other = data;
        other[7] = 0x55;
        assert_eq!(frame_checksum(0x110, &other), c);
        // Another id gives another checksum.
        assert_ne!(frame_checksum(0x111, &data), c);
    }

    #[test]
    fn counter_wraps_after_fifteen() {
        assert_eq!(next_counter(0), 1);
        assert_eq!(next_counter(14), 15);
        assert_eq!(next_counter(15), 0);
    }
}
