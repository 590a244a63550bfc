//! # v2t-fuzz — hostile input for every parser and decoder
//!
//! A mutation harness on stable Rust: the shipped files (and what the pipeline writes from them:
//! grounded scenarios, priors, runs, MCAP recordings, CAN and link frames) are the seeds; each
//! mutant is a seeded copy changed one to four times ([`mutate`]: numbers swapped for extreme ones,
//! bytes flipped, ranges dropped or repeated, lines moved, truncation) and is read by the real
//! reader and what consumes its result ([`targets`]). A refusal is a correct answer; a panic, an
//! abort (an allocation refused under the memory cap the caller sets) or a hang is a finding, kept
//! as a file to add to the regression seeds (`tests/fuzz/regressions/<kind>/`) once fixed.
//!
//! ```sh
//! cargo build --release -p v2t-fuzz
//! (ulimit -v 4194304; ./target/release/v2t-fuzz --mutants 1000 --budget-s 600)
//! ```

pub mod harness;
pub mod mutate;
pub mod targets;
