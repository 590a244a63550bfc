//! The builtin driver models' parameters. Their only source is `config/vut/builtin/*.toml`, one
//! file per model: the build script (`shared/sim/build.rs`) reads them and writes one function per
//! file, so a file that does not parse, names a field its model lacks or misses one fails the build.

include!(concat!(env!("OUT_DIR"), "/builtin_vut.rs"));
