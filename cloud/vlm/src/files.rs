//! The checks of the files under `config/vlm/` that the workspace's configuration test runs.

use std::path::Path;

use crate::cassette::{Cassette, MANIFEST_FILE, SEMANTICS_FILE, semantics_text};
use crate::prompt::Prompt;
use crate::{Mode, VlmConfig, VlmError, abstract_video};

/// Checks one file under `config/vlm/`: a prompt (`*.md`) parses; a cassette's `cassette.json`
/// replays offline to the `semantics.json` beside it, byte for byte; an exchange file is listed by
/// its cassette; a `semantics.json` is valid semantics. Any other file is an error.
pub fn check_config_file(path: &Path) -> Result<(), VlmError> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
    let dir = path.parent().unwrap_or(Path::new("."));
    let problem = |p: String| Err(VlmError::Cassette { dir: dir.to_owned(), problem: p });
    if name.ends_with(".md") {
        return Prompt::load(path).map(drop).map_err(VlmError::from);
    }
    let cassette = Cassette::load(dir)?;
    if name == MANIFEST_FILE {
        let m = &cassette.manifest;
        let video = Path::new(&m.video_file);
        let replayed = abstract_video(video, m.pet_label_s, &VlmConfig::default(), &Mode::Replay(dir.to_owned()))?;
        let text = semantics_text(&replayed.semantics)
            .map_err(|e| VlmError::Cassette { dir: dir.to_owned(), problem: e.to_string() })?;
        let recorded = v2t_files::bounds::read_text_within(&dir.join(SEMANTICS_FILE), v2t_files::bounds::SEMANTICS)
            .unwrap_or_default();
        if text != recorded {
            return problem(format!("the replay does not reproduce {SEMANTICS_FILE}"));
        }
        Ok(())
    } else if name == SEMANTICS_FILE {
        let text = v2t_files::bounds::read_text_within(path, v2t_files::bounds::SEMANTICS)
            .map_err(|e| VlmError::Cassette { dir: dir.to_owned(), problem: format!("{name}: {e}") })?;
        v2t_model::semantics::parse_semantics_json(&text)
            .map(drop)
            .map_err(|e| VlmError::Cassette { dir: dir.to_owned(), problem: format!("{name}: {e}") })
    } else if cassette.manifest.exchanges.iter().any(|e| e == name) {
        Ok(())
    } else {
        problem(format!("{name} is not part of the cassette (not listed in {MANIFEST_FILE})"))
    }
}
