//! The JSON documents a user writes: scenarios, rigs, controller settings, scenes, studies.
//! Each is read as if it were a file in `fixtures/`, so its relative paths resolve to the
//! repository's fixtures; text that is not UTF-8 is refused before the parser, as reading the
//! file refuses it.

use std::path::{Path, PathBuf};

use scanhil_controller::rig::Rig;
use scanhil_controller::run::plan::ScanPlan;
use scanhil_controller::run::scenario::Scenario;
use scanhil_controller::settings::ControllerSettings;
use scanhil_emulator::plant::Plant;
use scanhil_emulator::scene::Scene;
use scanhil_lab::study::plan::Study;
use scanhil_scene::truth::TrueScene;

use crate::{repository_root, select};

/// A file `name` in the fixtures' folder `folder`: where a fuzzed document is said to be.
fn fixture(folder: &str, name: &str) -> PathBuf {
    repository_root().join("fixtures").join(folder).join(name)
}

/// A scenario: parsed and checked, checked again (an override re-runs the same check), and a
/// scenario that passes planned as `scanhil scan` plans it before any link opens (the
/// controller built and checked against the rig, the coil power, the lead-in, the
/// prediction).
pub fn scenario(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let origin = fixture("scenarios", "fuzz.json");
    let Ok(scenario) = Scenario::from_json_str(text, &origin) else {
        return;
    };
    if let Err(error) = scenario.check() {
        panic!("a loaded scenario fails its own check: {error}");
    }
    let _ = ScanPlan::new(&scenario);
}

/// The other documents (byte 0 picks): a rig; controller settings, built into the loop's
/// controller; a scene, built into the emulator's plant; a study; a scene's true surface.
pub fn documents(data: &[u8]) {
    let Some((kind, bytes)) = select(data, 5) else {
        return;
    };
    let Ok(text) = std::str::from_utf8(bytes) else {
        return;
    };
    match kind {
        0 => {
            let _ = Rig::from_json_str(text, &fixture("rigs", "fuzz.json"));
        }
        1 => {
            let origin = fixture("controllers", "fuzz.json");
            if let Ok(settings) = ControllerSettings::from_json_str(text, &origin) {
                let _ = settings.build();
            }
        }
        2 => {
            if let Ok(scene) = Scene::from_json_str(text, &fixture("scenes", "fuzz.json")) {
                let _ = Plant::from_scene(&scene);
            }
        }
        3 => {
            if let Ok(study) = Study::from_json_str(text, &fixture("studies", "fuzz.json")) {
                assert!(
                    !study.variants.is_empty(),
                    "a study without variants loaded"
                );
                let _ = study.keys();
            }
        }
        _ => {
            let origin = fixture("scenes", "fuzz.json");
            let _ = TrueScene::from_json_str(text, Path::new(&origin));
        }
    }
}
