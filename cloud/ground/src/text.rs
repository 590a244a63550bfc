//! Lexical similarity for retrieval: a small tokenizer and suffix stemmer, and Okapi BM25 over the
//! fragments' generated descriptions.
//!
//! The vocabulary on both sides is small and technical (lanes, arms, turns, merges), so a crude
//! stemmer that maps `merging`, `merges` and `merge` to one stem does most of the work; number
//! words become digits so that "four-arm" meets "4-arm".

use std::collections::HashMap;

/// BM25 term-frequency saturation.
pub const BM25_K1: f64 = 1.2;
/// BM25 length normalisation.
pub const BM25_B: f64 = 0.75;

/// Words that carry no meaning for retrieval.
const STOP_WORDS: &[&str] = &[
    "a", "about", "after", "all", "an", "and", "any", "are", "as", "at", "be", "before", "by", "each", "for", "from",
    "has", "have", "he", "her", "his", "in", "into", "is", "it", "its", "it's", "of", "on", "or", "out", "over", "she",
    "so", "than", "that", "the", "their", "them", "then", "there", "these", "they", "this", "to", "up", "was", "were",
    "what", "when", "where", "which", "while", "who", "with", "without",
];

/// Number words, as digits.
const NUMBERS: &[(&str, &str)] =
    &[("one", "1"), ("two", "2"), ("three", "3"), ("four", "4"), ("five", "5"), ("six", "6"), ("eight", "8")];

/// Splits `text` into lower-case stems, dropping stop words.
pub fn tokenize(text: &str) -> Vec<String> {
    text.split(|c: char| !c.is_alphanumeric())
        .filter(|w| !w.is_empty())
        .map(str::to_lowercase)
        .filter(|w| !STOP_WORDS.contains(&w.as_str()))
        .map(|w| NUMBERS.iter().find(|(word, _)| *word == w).map_or_else(|| stem(&w), |(_, digit)| (*digit).to_owned()))
        .filter(|w| !w.is_empty())
        .collect()
}

/// A light suffix stemmer: plural `-s`/`-es`/`-ies`, `-ing`, `-ed`, `-ly`, a final `-e`, and the
/// doubled consonant those leave (`cutting` → `cut`). Words of three letters or fewer are kept.
pub fn stem(word: &str) -> String {
    let mut w = word.to_owned();
    if !w.is_ascii() || w.len() <= 3 {
        return w;
    }
    if let Some(base) = w.strip_suffix("ies") {
        w = format!("{base}y");
    } else if let Some(base) = w.strip_suffix("sses") {
        w = format!("{base}ss");
    } else if let Some(base) = w.strip_suffix("es")
        && (base.ends_with("ss") || base.ends_with('x') || base.ends_with("ch") || base.ends_with("sh"))
    {
        w = base.to_owned();
    } else if w.ends_with('s') && !w.ends_with("ss") && !w.ends_with("us") && !w.ends_with("is") {
        w.pop();
    }
    for suffix in ["ing", "ed", "ly"] {
        if let Some(base) = w.strip_suffix(suffix)
            && base.len() >= 3
            && base.chars().any(is_vowel)
            && !(suffix == "ed" && base.ends_with('e'))
        {
            w = undouble(base);
            break;
        }
    }
    if w.len() > 3 && w.ends_with('e') && !w.ends_with("ee") {
        w.pop();
    }
    w
}

fn is_vowel(c: char) -> bool {
    matches!(c, 'a' | 'e' | 'i' | 'o' | 'u' | 'y')
}

/// `cutt` → `cut`, `stopp` → `stop`; `fall`, `pass`, `buzz` stay.
fn undouble(base: &str) -> String {
    let mut chars = base.chars().rev();
    match (chars.next(), chars.next()) {
        (Some(a), Some(b)) if a == b && !is_vowel(a) && !matches!(a, 'l' | 's' | 'z') => {
            base.get(..base.len() - 1).unwrap_or(base).to_owned()
        }
        _ => base.to_owned(),
    }
}

/// An Okapi BM25 index over a fixed set of documents.
#[derive(Debug, Clone)]
pub struct Bm25 {
    docs: Vec<HashMap<String, f64>>,
    lengths: Vec<f64>,
    avg_length: f64,
    doc_freq: HashMap<String, f64>,
}

impl Bm25 {
    /// Indexes `docs` (already tokenized).
    pub fn new(docs: &[Vec<String>]) -> Self {
        let mut doc_freq: HashMap<String, f64> = HashMap::new();
        let mut counted = Vec::with_capacity(docs.len());
        for tokens in docs {
            let mut tf: HashMap<String, f64> = HashMap::new();
            for t in tokens {
                *tf.entry(t.clone()).or_insert(0.0) += 1.0;
            }
            for t in tf.keys() {
                *doc_freq.entry(t.clone()).or_insert(0.0) += 1.0;
            }
            counted.push(tf);
        }
        let lengths: Vec<f64> = docs.iter().map(|d| d.len() as f64).collect();
        let avg_length = if lengths.is_empty() { 0.0 } else { lengths.iter().sum::<f64>() / lengths.len() as f64 };
        Self { docs: counted, lengths, avg_length, doc_freq }
    }

    /// Inverse document frequency of `term`, the non-negative (Lucene) form.
    fn idf(&self, term: &str) -> f64 {
        let n = self.docs.len() as f64;
        let df = self.doc_freq.get(term).copied().unwrap_or(0.0);
        (1.0 + (n - df + 0.5) / (df + 0.5)).ln()
    }

    /// BM25 score of document `doc` for the (tokenized) query; each distinct query term counts once.
    pub fn score(&self, doc: usize, query: &[String]) -> f64 {
        let (Some(tf), Some(&len)) = (self.docs.get(doc), self.lengths.get(doc)) else { return 0.0 };
        let norm = if self.avg_length > 0.0 { len / self.avg_length } else { 1.0 };
        let mut seen: Vec<&str> = Vec::new();
        let mut total = 0.0;
        for term in query {
            if seen.contains(&term.as_str()) {
                continue;
            }
            seen.push(term);
            let f = tf.get(term).copied().unwrap_or(0.0);
            if f > 0.0 {
                total += self.idf(term) * f * (BM25_K1 + 1.0) / (f + BM25_K1 * (1.0 - BM25_B + BM25_B * norm));
            }
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inflections_share_a_stem() {
        for group in [
            &["merge", "merges", "merging", "merged"][..],
            &["turn", "turns", "turning", "turned"],
            &["cut", "cuts", "cutting"],
            &["lane", "lanes"],
            &["change", "changes", "changing"],
            &["cross", "crosses", "crossing"],
            &["yield", "yields", "yielding"],
            &["stop", "stopped", "stopping"],
        ] {
            let stems: Vec<String> = group.iter().map(|w| stem(w)).collect();
            assert!(stems.iter().all(|s| *s == stems[0]), "{group:?} → {stems:?}");
        }
        assert_eq!(stem("pass"), "pass");
        assert_eq!(stem("bus"), "bus");
    }

    #[test]
    fn tokens_are_lower_case_stems_without_stop_words_and_with_digits() {
        assert_eq!(tokenize("A four-arm Intersection, turning left!"), ["4", "arm", "intersection", "turn", "left"]);
        assert_eq!(tokenize("cut-in on the on-ramp"), ["cut", "ramp"]);
        assert!(tokenize("the of and").is_empty());
    }

    #[test]
    fn bm25_prefers_the_document_that_shares_rare_terms() {
        let docs: Vec<Vec<String>> = [
            "4-arm intersection, unprotected left turn against oncoming traffic",
            "2-lane multi-lane segment, fits lane changes and cut-ins",
            "merge: lane drop, on-ramp acceleration lane, merging",
        ]
        .iter()
        .map(|d| tokenize(d))
        .collect();
        let index = Bm25::new(&docs);
        let best = |q: &str| {
            let q = tokenize(q);
            (0..3).max_by(|&a, &b| index.score(a, &q).total_cmp(&index.score(b, &q))).unwrap()
        };
        assert_eq!(best("an oncoming SUV turns left in front of the ego"), 0);
        assert_eq!(best("a sedan cuts in from the right lane"), 1);
        assert_eq!(best("a truck merges from the on-ramp"), 2);
        assert_eq!(index.score(0, &tokenize("nothing shared here")), 0.0);
        assert_eq!(index.score(7, &tokenize("merge")), 0.0);
    }
}
