//! Seeded mutations of a file's bytes: what a careless editor, a damaged disk or a hostile peer
//! makes of it. Text files get most of their mutations where the crashes were (numbers swapped for
//! extreme ones, lines dropped or repeated); binary files get bit flips, overwritten words and
//! truncation. The same `(seed, bytes)` always gives the same mutant.

/// A small deterministic generator (SplitMix64): the mutants must be reproducible from their
/// index, not statistically perfect.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator for `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next_u64() % n as u64) as usize }
    }

    /// One of `items` (`None` when empty).
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> Option<&'a T> {
        items.get(self.below(items.len()))
    }
}

/// Numbers that broke or could break a reader: beyond every bound, not numbers, at the edges of
/// integer types, denormal, negative zero.
pub const EXTREME_NUMBERS: &[&str] = &[
    "1e308",
    "-1e308",
    "1e400",
    "1e300",
    "1e9",
    "-1e9",
    "1e7",
    "1e6",
    "0",
    "-0",
    "-1",
    "0.0",
    "1e-320",
    "1e-9",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "9223372036854775807",
    "-9223372036854775808",
    "9.2e18",
    "2147483648",
    "65536",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e99999",
];

/// Bytes that end, open or separate something in one of our formats.
const SPECIAL_BYTES: &[u8] = b"\0\xff\x7f\x80\"'<>{}[]=,:\n-.e9#&/\\";

/// Whether the file is text (mutated with number and line operations as well).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    /// TOML, JSON, XML.
    Text,
    /// MCAP, CAN frames, link frames.
    Binary,
}

/// `seed` mutated one to four times by `rng`.
pub fn mutate(rng: &mut Rng, seed: &[u8], form: Form) -> Vec<u8> {
    let mut out = seed.to_vec();
    let rounds = 1 + rng.below(4);
    for _ in 0..rounds {
        let op = rng.below(if form == Form::Text { 12 } else { 7 });
        match op {
            0 => flip_bit(rng, &mut out),
            1 => special_byte(rng, &mut out),
            2 => delete_range(rng, &mut out),
            3 => duplicate_range(rng, &mut out),
            4 => truncate(rng, &mut out),
            5 => random_bytes(rng, &mut out),
            6 => overwrite_word(rng, &mut out),
            7..=9 => swap_number(rng, &mut out),
            10 => insert_number(rng, &mut out),
            _ => line_operation(rng, &mut out),
        }
    }
    out
}

fn flip_bit(rng: &mut Rng, out: &mut [u8]) {
    let i = rng.below(out.len());
    let bit = 1u8 << rng.below(8);
    if let Some(b) = out.get_mut(i) {
        *b ^= bit;
    }
}

fn special_byte(rng: &mut Rng, out: &mut [u8]) {
    let i = rng.below(out.len());
    let value = rng.pick(SPECIAL_BYTES).copied().unwrap_or(0);
    if let Some(b) = out.get_mut(i) {
        *b = value;
    }
}

fn delete_range(rng: &mut Rng, out: &mut Vec<u8>) {
    if out.is_empty() {
        return;
    }
    let start = rng.below(out.len());
    let len = (1 + rng.below(64)).min(out.len() - start);
    out.drain(start..start + len);
}

fn duplicate_range(rng: &mut Rng, out: &mut Vec<u8>) {
    if out.is_empty() {
        return;
    }
    let start = rng.below(out.len());
    let len = (1 + rng.below(256)).min(out.len() - start);
    let chunk: Vec<u8> = out.get(start..start + len).map(<[u8]>::to_vec).unwrap_or_default();
    let at = rng.below(out.len() + 1);
    out.splice(at..at, chunk);
}

fn truncate(rng: &mut Rng, out: &mut Vec<u8>) {
    let at = rng.below(out.len() + 1);
    out.truncate(at);
}

fn random_bytes(rng: &mut Rng, out: &mut Vec<u8>) {
    let at = rng.below(out.len() + 1);
    let n = 1 + rng.below(16);
    let bytes: Vec<u8> = (0..n).map(|_| (rng.next_u64() & 0xff) as u8).collect();
    out.splice(at..at, bytes);
}

/// Overwrites 1, 2, 4 or 8 bytes with an integer at the edge of its type (lengths, counts,
/// offsets in binary formats).
fn overwrite_word(rng: &mut Rng, out: &mut [u8]) {
    let width = *rng.pick(&[1usize, 2, 4, 8]).unwrap_or(&4);
    let value: u64 =
        *rng.pick(&[0, u64::MAX, 0x7f, 0x80, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, 1 << 40]).unwrap_or(&0);
    if out.len() < width {
        return;
    }
    let at = rng.below(out.len() - width + 1);
    for (k, b) in out.iter_mut().skip(at).take(width).enumerate() {
        *b = (value >> (8 * k)) as u8;
    }
}

/// Byte ranges of the numbers in a text: a digit run (with sign, point and exponent) that does
/// not continue a name (`bv1`, `S5`).
pub fn number_spans(text: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let starts = text.get(i).is_some_and(u8::is_ascii_digit)
            || (text.get(i) == Some(&b'-') && text.get(i + 1).is_some_and(u8::is_ascii_digit));
        let after_name =
            i > 0 && text.get(i - 1).is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_' || *c == b'.');
        if starts && !after_name {
            let mut j = i + 1;
            while text.get(j).is_some_and(|c| c.is_ascii_digit() || matches!(c, b'.' | b'e' | b'E' | b'+' | b'-')) {
                j += 1;
            }
            spans.push((i, j));
            i = j;
        } else {
            i += 1;
        }
    }
    spans
}

fn swap_number(rng: &mut Rng, out: &mut Vec<u8>) {
    let spans = number_spans(out);
    let (Some(&(a, b)), Some(n)) = (rng.pick(&spans), rng.pick(EXTREME_NUMBERS)) else {
        return special_byte(rng, out);
    };
    out.splice(a..b, n.bytes());
}

fn insert_number(rng: &mut Rng, out: &mut Vec<u8>) {
    let at = rng.below(out.len() + 1);
    let n = rng.pick(EXTREME_NUMBERS).copied().unwrap_or("0");
    out.splice(at..at, n.bytes());
}

/// Drops, repeats or moves one line.
fn line_operation(rng: &mut Rng, out: &mut Vec<u8>) {
    let starts: Vec<usize> =
        std::iter::once(0).chain(out.iter().enumerate().filter(|(_, b)| **b == b'\n').map(|(i, _)| i + 1)).collect();
    let k = rng.below(starts.len());
    let (Some(&a), b) = (starts.get(k), starts.get(k + 1).copied().unwrap_or(out.len())) else {
        return;
    };
    if a > b || b > out.len() {
        return;
    }
    let line: Vec<u8> = out.get(a..b).map(<[u8]>::to_vec).unwrap_or_default();
    match rng.below(3) {
        0 => {
            out.drain(a..b);
        }
        1 => {
            let times = 1 + rng.below(8);
            for _ in 0..times {
                out.splice(a..a, line.iter().copied());
            }
        }
        _ => {
            out.drain(a..b);
            let to = starts.get(rng.below(starts.len())).copied().unwrap_or(0).min(out.len());
            out.splice(to..to, line);
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_mutant() {
        let text = b"a = 1.5\nb = [2, -3e4]\nname = \"bv1\"\n";
        for seed in 0..200 {
            let (mut r1, mut r2) = (Rng::new(seed), Rng::new(seed));
            assert_eq!(mutate(&mut r1, text, Form::Text), mutate(&mut r2, text, Form::Text));
        }
        let differ = (0..200).filter(|s| mutate(&mut Rng::new(*s), text, Form::Text) != text.to_vec()).count();
        assert!(differ > 150, "most mutants differ from their seed: {differ} of 200");
    }

    #[test]
    fn numbers_are_found_but_not_inside_names() {
        let text = b"bv1 = 12.5e-3, x = -4, S5/fwd/0 y=.5";
        let spans: Vec<&str> =
            number_spans(text).iter().map(|(a, b)| std::str::from_utf8(&text[*a..*b]).unwrap()).collect();
        assert_eq!(spans, ["12.5e-3", "-4", "0"]);
    }

    #[test]
    fn mutating_empty_or_tiny_input_never_panics() {
        for seed in 0..2000 {
            for input in [&b""[..], b"1", b"\n", b"ab"] {
                let _ = mutate(&mut Rng::new(seed), input, Form::Text);
                let _ = mutate(&mut Rng::new(seed), input, Form::Binary);
            }
        }
    }
}
