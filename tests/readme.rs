//! The case-file reference in README.md and the parser cannot drift apart: the README's example
//! case parses and validates with the parser, and every key that a shipped case uses is
//! documented in the reference.

use fdfsi::case::Case;
use std::collections::BTreeSet;
use std::path::Path;

fn readme_case_section() -> String {
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let start = text.find("## Case files").expect("README has a '## Case files' section");
    let end = text[start..].find("\n## Built-in cases").map_or(text.len(), |e| start + e);
    text[start..end].to_string()
}

/// The ```toml blocks of `text`.
fn toml_blocks(text: &str) -> Vec<String> {
    let mut blocks = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("```toml\n") {
        let body = &rest[i + 8..];
        let j = body.find("```").expect("closed code block");
        blocks.push(body[..j].to_string());
        rest = &body[j + 3..];
    }
    blocks
}

#[test]
fn the_readme_example_case_is_valid() {
    let blocks = toml_blocks(&readme_case_section());
    assert!(!blocks.is_empty(), "the case-file reference has no ```toml example");
    for (k, b) in blocks.iter().enumerate() {
        let case = Case::from_toml_str(b, &format!("README.md toml block {}", k + 1)).unwrap_or_else(|e| panic!("{e}"));
        case.validate("README.md").unwrap_or_else(|e| panic!("README.md toml block {}: {e}", k + 1));
    }
}

/// Keys (`name =` at the start of a line or inside an inline table) of a TOML text.
fn keys(text: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for line in text.lines() {
        // Drop comments and the contents of strings (which may hold `=`).
        let mut code = String::new();
        let mut in_string = false;
        for c in line.chars() {
            match c {
                '"' => in_string = !in_string,
                '#' if !in_string => break,
                _ if !in_string => code.push(c),
                _ => {}
            }
        }
        let line = code.as_str();
        for part in line.split(['{', ',']) {
            if let Some((k, _)) = part.split_once('=') {
                let k = k.trim();
                if !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                    out.insert(k.to_string());
                }
            }
        }
    }
    out
}

#[test]
fn every_key_of_the_shipped_cases_is_documented() {
    let reference = readme_case_section();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let mut missing = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            for k in keys(&std::fs::read_to_string(&path).unwrap()) {
                if !reference.contains(&format!("{k} =")) && !reference.contains(&format!("`{k}`")) {
                    missing.push(format!("{k} (in {})", path.file_name().unwrap().to_string_lossy()));
                }
            }
        }
    }
    assert!(missing.is_empty(), "keys used by cases/ but not documented in README's case-file reference: {missing:?}");
}
