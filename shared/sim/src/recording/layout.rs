//! The byte layout of an MCAP file, checked before the `mcap` crate reads it: every record's
//! length within what remains of the file (or of its chunk), and every length prefix inside a record
//! (strings, maps, byte arrays) within what remains of the record. The crate allocates what a length
//! prefix says before it reads: a file that claims a 4 GB string aborted the process (found by the
//! mutation harness); here it is an error naming the record and the field.

/// The magic at both ends of an MCAP file.
const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// Checks the layout of a whole file.
pub fn check(bytes: &[u8]) -> Result<(), String> {
    let body = bytes.strip_prefix(MAGIC).ok_or("not an MCAP file: the magic is missing")?;
    records(body, "the file", true)
}

/// The records of `data` (the file after its magic, or a chunk's records).
fn records(mut data: &[u8], within: &str, top: bool) -> Result<(), String> {
    let mut index = 0usize;
    while !data.is_empty() {
        if top && data == MAGIC {
            return Ok(());
        }
        let mut c = Cursor { data, field: "opcode" };
        let op = c.u8()?;
        c.field = "record length";
        let len = c.u64()?;
        let content = c.take(len).map_err(|e| format!("{within}, record {index} (opcode 0x{op:02x}): {e}"))?;
        fields(op, content).map_err(|e| format!("{within}, record {index} (opcode 0x{op:02x}): {e}"))?;
        data = c.data;
        index += 1;
    }
    Ok(())
}

/// The length-prefixed fields of one record, per the MCAP specification's layout of each opcode.
fn fields(op: u8, content: &[u8]) -> Result<(), String> {
    let mut c = Cursor { data: content, field: "" };
    match op {
        // Header: profile, library.
        0x01 => {
            c.string("profile")?;
            c.string("library")?;
        }
        // Schema: id, name, encoding, data.
        0x03 => {
            c.fixed("id", 2)?;
            c.string("name")?;
            c.string("encoding")?;
            c.bytes_u32("data")?;
        }
        // Channel: id, schema id, topic, message encoding, metadata.
        0x04 => {
            c.fixed("id, schema_id", 4)?;
            c.string("topic")?;
            c.string("message_encoding")?;
            c.string_map("metadata")?;
        }
        // Chunk: times, uncompressed size and CRC, compression, records.
        0x06 => {
            c.fixed("message_start_time, message_end_time", 16)?;
            c.field = "uncompressed_size";
            let size = c.u64()?;
            c.fixed("uncompressed_crc", 4)?;
            let compression = c.string("compression")?;
            c.field = "records";
            let len = c.u64()?;
            let inner = c.take(len)?;
            if compression.is_empty() {
                if size != len {
                    return Err(format!("uncompressed_size {size} is not the {len} bytes of its records"));
                }
                records(inner, "a chunk", false)?;
            }
        }
        // Message index: channel id, records.
        0x07 => {
            c.fixed("channel_id", 2)?;
            c.bytes_u32("records")?;
        }
        // Chunk index: times, offsets, message index offsets, length, compression, sizes.
        0x08 => {
            c.fixed("message_start_time … chunk_length", 32)?;
            c.bytes_u32("message_index_offsets")?;
            c.fixed("message_index_length", 8)?;
            c.string("compression")?;
            c.fixed("compressed_size, uncompressed_size", 16)?;
        }
        // Attachment: times, name, media type, data, CRC.
        0x09 => {
            c.fixed("log_time, create_time", 16)?;
            c.string("name")?;
            c.string("media_type")?;
            c.bytes_u64("data")?;
        }
        // Attachment index: offset, length, times, size, name, media type.
        0x0A => {
            c.fixed("offset … data_size", 40)?;
            c.string("name")?;
            c.string("media_type")?;
        }
        // Statistics: counts and times, channel message counts.
        0x0B => {
            c.fixed("message_count … message_end_time", 42)?;
            c.bytes_u32("channel_message_counts")?;
        }
        // Metadata: name, metadata.
        0x0C => {
            c.string("name")?;
            c.string_map("metadata")?;
        }
        // Metadata index: offset, length, name.
        0x0D => {
            c.fixed("offset, length", 16)?;
            c.string("name")?;
        }
        // Footer, message, summary offset, data end, and opcodes this reader does not know: no
        // length prefix the crate allocates from.
        _ => {}
    }
    Ok(())
}

/// Reads little-endian fields from a record, each within what remains.
struct Cursor<'a> {
    data: &'a [u8],
    field: &'a str,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: u64) -> Result<&'a [u8], String> {
        let remain = self.data.len();
        let n = usize::try_from(n).ok().filter(|n| *n <= remain).ok_or_else(|| {
            format!("field `{}` declares {} bytes, {remain} remain", self.field, v2t_model::validate::shown(n as f64))
        })?;
        let (head, tail) = self.data.split_at(n);
        self.data = tail;
        Ok(head)
    }

    fn fixed(&mut self, field: &'a str, n: u64) -> Result<(), String> {
        self.field = field;
        self.take(n).map(drop)
    }

    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?.first().copied().unwrap_or(0))
    }

    fn u32(&mut self) -> Result<u32, String> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([0, 1, 2, 3].map(|i| b.get(i).copied().unwrap_or(0))))
    }

    fn u64(&mut self) -> Result<u64, String> {
        let b = self.take(8)?;
        Ok(u64::from_le_bytes([0, 1, 2, 3, 4, 5, 6, 7].map(|i| b.get(i).copied().unwrap_or(0))))
    }

    fn string(&mut self, field: &'a str) -> Result<&'a [u8], String> {
        self.field = field;
        let n = self.u32()?;
        self.take(u64::from(n))
    }

    fn bytes_u32(&mut self, field: &'a str) -> Result<(), String> {
        self.string(field).map(drop)
    }

    fn bytes_u64(&mut self, field: &'a str) -> Result<(), String> {
        self.field = field;
        let n = self.u64()?;
        self.take(n).map(drop)
    }

    /// A map of strings to strings: its byte length, then key and value strings within it.
    fn string_map(&mut self, field: &'a str) -> Result<(), String> {
        let entries = self.string(field)?;
        let mut inner = Cursor { data: entries, field };
        while !inner.data.is_empty() {
            inner.string(field)?;
            inner.string(field)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn record(op: u8, content: &[u8]) -> Vec<u8> {
        let mut r = vec![op];
        r.extend((content.len() as u64).to_le_bytes());
        r.extend(content);
        r
    }

    fn string(s: &[u8]) -> Vec<u8> {
        let mut v = (s.len() as u32).to_le_bytes().to_vec();
        v.extend(s);
        v
    }

    #[test]
    fn a_well_formed_file_passes_and_a_lying_prefix_is_named() {
        let mut metadata = string(b"run");
        let map: Vec<u8> = [string(b"k"), string(b"v")].concat();
        metadata.extend(string(&map));
        let mut file = MAGIC.to_vec();
        file.extend(record(0x01, &[string(b"video2track"), string(b"lib")].concat()));
        file.extend(record(0x0C, &metadata));
        file.extend(MAGIC);
        check(&file).unwrap();
        // The map's inner value claims 4 GB (what aborted the reader).
        let mut lying = file.clone();
        let at = lying.windows(5).position(|w| w == [1, 0, 0, 0, b'v']).unwrap();
        lying[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = check(&lying).unwrap_err();
        assert!(
            e.contains("record 1 (opcode 0x0c)") && e.contains("metadata") && e.contains("4294967295 bytes"),
            "{e}"
        );
        // A record longer than the file.
        let mut long = file.clone();
        long[9..17].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(check(&long).unwrap_err().contains("record length") || check(&long).is_err());
        assert!(check(b"not mcap").unwrap_err().contains("magic"));
    }
}
