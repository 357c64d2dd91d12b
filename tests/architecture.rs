//! ARCHITECTURE.md's file map names every source file, and only files that exist; shared
//! layers import no system (the module rules stated there).

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn sources() -> Vec<String> {
    let mut files = Vec::new();
    rust_files(&root().join("src"), &mut files);
    files
        .iter()
        .map(|p| p.strip_prefix(root()).unwrap().to_string_lossy().replace('\\', "/"))
        .collect()
}

#[test]
fn the_file_map_names_every_source_file_and_no_other() {
    let doc = fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let map = &doc[doc.find("## File map").expect("ARCHITECTURE.md has a file map")..];
    let listed: BTreeSet<&str> = map
        .lines()
        .filter_map(|l| l.strip_prefix("| `src/"))
        .filter_map(|l| l.split('`').next())
        .collect();
    let files: BTreeSet<String> =
        sources().into_iter().map(|f| f.trim_start_matches("src/").to_string()).collect();
    let missing: Vec<_> = files.iter().filter(|f| !listed.contains(f.as_str())).collect();
    let gone: Vec<_> = listed.iter().filter(|f| !files.contains(**f)).collect();
    assert!(missing.is_empty(), "source files missing from the file map: {missing:?}");
    assert!(gone.is_empty(), "file map entries with no file: {gone:?}");
}

#[test]
fn shared_layers_import_no_system() {
    let systems = [
        "particles",
        "cloth",
        "rigid",
        "constraints",
        "anim",
        "mocap",
        "ik",
        "fluid",
        "crowd",
        "rods",
        "skin",
    ];
    let shared = ["error", "batch", "math", "linalg", "spline", "geometry", "rotation", "ode"];
    let mut offenders = Vec::new();
    for file in sources() {
        let module = file.trim_start_matches("src/").split(['/', '.']).next().unwrap();
        if !shared.contains(&module) && module != "snapshot" {
            continue;
        }
        let text = fs::read_to_string(root().join(&file)).unwrap();
        for line in text.lines().filter(|l| !l.trim_start().starts_with("//")) {
            for system in systems {
                if line.contains(&format!("crate::{system}::")) {
                    offenders.push(format!("{file}: {}", line.trim()));
                }
            }
        }
    }
    assert!(offenders.is_empty(), "shared layers importing a system: {offenders:#?}");
}
