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

/// Subnormal numbers (and the smallest normal one): they pass every "> 0" check and are no length,
/// radius or time at all.
pub const SUBNORMAL_NUMBERS: &[&str] =
    &["5e-324", "-5e-324", "4.9e-324", "1e-310", "-1e-310", "2.5e-315", "1e-320", "2.2250738585072014e-308"];

/// Factors that turn a sane number into a plausible-looking wrong one (silent nonsense: a sign
/// flipped, a unit off by a thousand).
const FACTORS: &[f64] = &[-1.0, 10.0, 1000.0, 1e-3, 0.5, 2.0, 1e6, -1e3];

/// Sizes an element is repeated to, bytes: within most bounds, around them, and past every one
/// (the largest, rarely: 300 MB on disk for each such mutant).
const HUGE_SIZES: &[usize] = &[64 << 10, 1 << 20, 5 << 20, 20 << 20];
/// Past every file's size bound (the largest is 256 MiB).
pub const PAST_EVERY_BOUND: usize = 300 << 20;

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
        let op = rng.below(if form == Form::Text { 17 } else { 8 });
        match (form, op) {
            (_, 0) => flip_bit(rng, &mut out),
            (_, 1) => special_byte(rng, &mut out),
            (_, 2) => delete_range(rng, &mut out),
            (_, 3) => duplicate_range(rng, &mut out),
            (_, 4) => truncate(rng, &mut out),
            (_, 5) => random_bytes(rng, &mut out),
            (_, 6) => overwrite_word(rng, &mut out),
            (Form::Binary, _) => {
                if repeat_to_huge(rng, &mut out, form) {
                    // One huge element per mutant is enough; more rounds would only copy it.
                    break;
                }
            }
            (Form::Text, 7..=9) => swap_number(rng, &mut out),
            (Form::Text, 10) => insert_number(rng, &mut out),
            (Form::Text, 11) => line_operation(rng, &mut out),
            (Form::Text, 12) => subnormal_number(rng, &mut out),
            (Form::Text, 13) => swap_fields(rng, &mut out),
            (Form::Text, 14) => scale_number(rng, &mut out),
            (Form::Text, 15) => set_field(rng, &mut out),
            (Form::Text, _) => {
                if repeat_to_huge(rng, &mut out, form) {
                    break;
                }
            }
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

/// Replaces one number of the text with one of `numbers`; whether the text had a number.
fn replace_number(rng: &mut Rng, out: &mut Vec<u8>, numbers: &[&str]) -> bool {
    let spans = number_spans(out);
    let (Some(&(a, b)), Some(n)) = (rng.pick(&spans), rng.pick(numbers)) else { return false };
    out.splice(a..b, n.bytes());
    true
}

fn swap_number(rng: &mut Rng, out: &mut Vec<u8>) {
    if !replace_number(rng, out, EXTREME_NUMBERS) {
        special_byte(rng, out);
    }
}

fn insert_number(rng: &mut Rng, out: &mut Vec<u8>) {
    let at = rng.below(out.len() + 1);
    let n = rng.pick(EXTREME_NUMBERS).copied().unwrap_or("0");
    out.splice(at..at, n.bytes());
}

fn subnormal_number(rng: &mut Rng, out: &mut Vec<u8>) {
    if !replace_number(rng, out, SUBNORMAL_NUMBERS) {
        insert_number(rng, out);
    }
}

/// Swaps two numbers of the text: fields that hold each other's values (a length where a speed
/// belongs, x for y, start for end).
fn swap_fields(rng: &mut Rng, out: &mut Vec<u8>) {
    let spans = number_spans(out);
    let (Some(&(a0, a1)), Some(&(b0, b1))) = (rng.pick(&spans), rng.pick(&spans)) else {
        return;
    };
    let ((a0, a1), (b0, b1)) = if a0 <= b0 { ((a0, a1), (b0, b1)) } else { ((b0, b1), (a0, a1)) };
    if a1 > b0 {
        return;
    }
    let (first, second) = (out.get(a0..a1).map(<[u8]>::to_vec), out.get(b0..b1).map(<[u8]>::to_vec));
    let (Some(first), Some(second)) = (first, second) else { return };
    out.splice(b0..b1, first);
    out.splice(a0..a1, second);
}

/// Multiplies one number by a factor that keeps it looking like a number of its kind.
fn scale_number(rng: &mut Rng, out: &mut Vec<u8>) {
    let spans = number_spans(out);
    let Some(&(a, b)) = rng.pick(&spans) else { return };
    let value = out.get(a..b).and_then(|t| std::str::from_utf8(t).ok()).and_then(|t| t.parse::<f64>().ok());
    let (Some(value), Some(k)) = (value, rng.pick(FACTORS)) else { return };
    let scaled = value * k;
    // Integers stay integers where they can (counts, ids, lengths of arrays).
    let text = if scaled.fract() == 0.0 && scaled.abs() < 1e15 { format!("{scaled:.0}") } else { format!("{scaled}") };
    out.splice(a..b, text.into_bytes());
}

/// Sets the value of one field (`key = value` in TOML, `"key": value` in JSON, `key="value"` in
/// XML) to an extreme number, a subnormal or an empty array, whatever the value was.
fn set_field(rng: &mut Rng, out: &mut Vec<u8>) {
    // The separators and where each value ends.
    let marks: Vec<(usize, u8)> = out
        .iter()
        .enumerate()
        .filter(|(i, c)| **c == b'=' || (**c == b':' && out.get(i.wrapping_sub(1)) == Some(&b'"')))
        .map(|(i, c)| (i, *c))
        .collect();
    let Some(&(at, sep)) = rng.pick(&marks) else { return };
    let start = at + 1 + out.iter().skip(at + 1).take_while(|c| **c == b' ').count();
    let quoted = sep == b'=' && out.get(start) == Some(&b'"') && out.get(at.wrapping_sub(1)) != Some(&b' ');
    let end = if quoted {
        // An XML attribute: the value between the quotes.
        let close = out.iter().skip(start + 1).position(|c| *c == b'"').map_or(out.len(), |p| start + 1 + p);
        return splice_value(rng, out, start + 1, close);
    } else {
        out.iter().skip(start).position(|c| matches!(c, b'\n' | b',' | b'}' | b']')).map_or(out.len(), |p| start + p)
    };
    splice_value(rng, out, start, end);
}

fn splice_value(rng: &mut Rng, out: &mut Vec<u8>, start: usize, end: usize) {
    if start > end || end > out.len() {
        return;
    }
    let value = match rng.below(4) {
        0 => rng.pick(SUBNORMAL_NUMBERS).copied().unwrap_or("5e-324"),
        1 => "[]",
        _ => rng.pick(EXTREME_NUMBERS).copied().unwrap_or("1e308"),
    };
    out.splice(start..end, value.bytes());
}

/// Repeats one element (a run of 1 to 12 lines in text, up to 4 KiB of bytes otherwise) right
/// after itself: 2 to 1,000 times (at most 1 MiB in all), or, one time in 16, until the whole is
/// one of [`HUGE_SIZES`] and, one of those in 256, [`PAST_EVERY_BOUND`]: an array repeated to a
/// huge length. Whether it grew huge.
fn repeat_to_huge(rng: &mut Rng, out: &mut Vec<u8>, form: Form) -> bool {
    if out.is_empty() {
        return false;
    }
    let (a, b) = match form {
        Form::Text => {
            let starts: Vec<usize> = std::iter::once(0)
                .chain(out.iter().enumerate().filter(|(_, c)| **c == b'\n').map(|(i, _)| i + 1))
                .filter(|i| *i < out.len())
                .collect();
            let k = rng.below(starts.len());
            let a = starts.get(k).copied().unwrap_or(0);
            let b = starts.get(k + 1 + rng.below(12)).copied().unwrap_or(out.len());
            (a, b)
        }
        Form::Binary => {
            let a = rng.below(out.len());
            (a, (a + 1 + rng.below(4096)).min(out.len()))
        }
    };
    let Some(chunk) = out.get(a..b).map(<[u8]>::to_vec) else { return false };
    if chunk.is_empty() {
        return false;
    }
    let huge = rng.below(16) == 0;
    let times = match (huge, rng.below(256)) {
        (true, 0) => PAST_EVERY_BOUND.saturating_sub(out.len()) / chunk.len(),
        (true, _) => rng.pick(HUGE_SIZES).copied().unwrap_or(1 << 20).saturating_sub(out.len()) / chunk.len(),
        (false, _) => (2 + rng.below(999)).min((1 << 20) / chunk.len()),
    };
    let copies = chunk.repeat(times);
    out.splice(b..b, copies);
    huge
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

    /// Each structure-aware kind does what it says on a known text.
    #[test]
    fn the_structure_aware_kinds_change_what_they_say() {
        let text = b"[[bvs]]\nid = \"bv1\"\nradius_m = 12.5\nangle_deg = 90\n";
        let as_text = |v: &[u8]| String::from_utf8_lossy(v).into_owned();
        let mut seen = [false; 4];
        for seed in 0..400 {
            let mut rng = Rng::new(seed);
            let mut out = text.to_vec();
            subnormal_number(&mut rng, &mut out);
            seen[0] |= SUBNORMAL_NUMBERS.iter().any(|n| as_text(&out).contains(&format!("= {n}\n")));
            let mut out = text.to_vec();
            swap_fields(&mut rng, &mut out);
            seen[1] |= as_text(&out).contains("radius_m = 90\nangle_deg = 12.5");
            let mut out = text.to_vec();
            scale_number(&mut rng, &mut out);
            seen[2] |= as_text(&out).contains("radius_m = 12500\n");
            let mut out = text.to_vec();
            set_field(&mut rng, &mut out);
            seen[3] |= as_text(&out).contains("id = []\n");
        }
        assert_eq!(seen, [true; 4]);
        // An element repeated stays whole (every copy a full line); some grow huge.
        let mut huge = 0;
        for seed in 0..200 {
            let mut out = text.to_vec();
            repeat_to_huge(&mut Rng::new(seed), &mut out, Form::Text);
            assert!(out.len() > text.len() && out.ends_with(b"\n"), "{}", out.len());
            assert!(as_text(&out).lines().all(|l| text.split(|c| *c == b'\n').any(|t| t == l.as_bytes())));
            huge += usize::from(out.len() >= 60 << 10);
        }
        assert!((3..=30).contains(&huge), "{huge} of 200 grew huge");
        // The XML attribute's value, between its quotes.
        let xml = br#"<geometry s="0" length="12.5"/>"#;
        let mut changed = false;
        for seed in 0..200 {
            let mut out = xml.to_vec();
            set_field(&mut Rng::new(seed), &mut out);
            changed |= as_text(&out).contains(r#"length="[]"/>"#);
        }
        assert!(changed);
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
