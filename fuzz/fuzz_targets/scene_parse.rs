//! Arbitrary bytes (as lossy UTF-8 text) as a scene file: `Scene::parse` must return a scene or
//! an error, never panic, and never touch the filesystem (the base directory does not exist;
//! only `Scene::to_mesh` reads files). A scene it returns has between one and `MAX_ENTRIES`
//! entries, each with a name, a path under the base directory (or absolute), and a usable
//! placement; an error that names a place names a line of the text.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use vps::scene::{Scene, SceneError, MAX_ENTRIES};

const BASE: &str = "/nonexistent/vps-fuzz/scene";

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let lines = text.split('\n').count();
    match Scene::parse(&text, Path::new(BASE)) {
        Ok(scene) => {
            assert!(!scene.entries.is_empty() && scene.entries.len() <= MAX_ENTRIES);
            assert!(scene.file.is_none());
            for e in &scene.entries {
                assert!(!e.name.is_empty());
                assert!(e.path.starts_with(BASE) || e.path.is_absolute(), "{:?}", e.path);
                assert!(e.line >= 1 && e.line <= lines, "line {} of {lines}", e.line);
                let t = e.placement;
                let (translation, rotation) = (t.pose.translation, t.pose.rotation);
                assert!(translation.is_finite());
                assert!(t.scale.is_finite() && t.scale > 0.0);
                assert!(rotation.is_finite());
                assert!((rotation.length() - 1.0).abs() < 1e-12, "{:?}", rotation);
                // A point near the origin lands somewhere finite unless the numbers are huge.
                if t.scale < 1e300 && translation.abs().max_element() < 1e300 {
                    assert!(t.apply(translation.signum()).is_finite());
                }
            }
        }
        Err(e) => {
            let at = match &e {
                SceneError::Syntax { at, .. }
                | SceneError::UnknownField { at, .. }
                | SceneError::MissingPath { at, .. }
                | SceneError::Invalid { at, .. }
                | SceneError::NonFinite { at, .. }
                | SceneError::BadScale { at, .. }
                | SceneError::ZeroQuaternion { at, .. } => Some(at),
                SceneError::NoEntries { .. } | SceneError::TooManyEntries { .. } => None,
                SceneError::Read { .. } | SceneError::Mesh { .. } | SceneError::Empty { .. } => {
                    panic!("parsing text reads no files: {e}")
                }
            };
            if let Some(at) = at {
                assert!(at.file.is_none());
                // Line 0 only when the TOML parser gives no place.
                assert!(at.line <= lines, "line {} of {lines}: {e}", at.line);
            }
            // Every message renders.
            let _ = e.to_string();
        }
    }
});
