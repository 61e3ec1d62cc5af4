//! The library's layers are one-way: `src/lib.rs` lists the top-level modules in dependency
//! order, and no module uses one listed after it (so there is no import cycle). References are
//! counted as `crate::NAME` paths outside comments and unit-test modules.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The top-level modules in the order `src/lib.rs` declares them.
fn declared_modules(src: &Path) -> Vec<String> {
    let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap();
    lib.lines().filter_map(|l| l.trim().strip_prefix("pub mod ")?.strip_suffix(';').map(str::to_string)).collect()
}

/// Every `.rs` file of module `name` (its file, or its folder).
fn module_files(src: &Path, name: &str) -> Vec<PathBuf> {
    let file = src.join(format!("{name}.rs"));
    if file.exists() {
        return vec![file];
    }
    let mut out = Vec::new();
    let mut dirs = vec![src.join(name)];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("{}: {e}", d.display())) {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out
}

/// The code of a file without its comments and its `#[cfg(test)]` module.
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    text.lines().map(|l| l.split("//").next().unwrap_or("")).collect::<Vec<_>>().join("\n")
}

/// The crate modules `text` refers to, with counts: `crate::NAME` and `crate::{NAME, ...}`.
fn references(text: &str, modules: &[String]) -> BTreeMap<String, usize> {
    let mut out = BTreeMap::new();
    let mut rest = text;
    while let Some(i) = rest.find("crate::") {
        rest = &rest[i + "crate::".len()..];
        let names: Vec<&str> = if let Some(group) = rest.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            group[..end].split(',').map(|s| s.trim().split("::").next().unwrap_or("")).collect()
        } else {
            vec![rest.split(|c: char| !(c.is_alphanumeric() || c == '_')).next().unwrap_or("")]
        };
        for n in names {
            if modules.iter().any(|m| m == n) {
                *out.entry(n.to_string()).or_insert(0) += 1;
            }
        }
    }
    out
}

#[test]
fn no_module_uses_one_declared_after_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let modules = declared_modules(&src);
    assert!(modules.len() >= 10, "lib.rs declares {modules:?}");
    let mut upward = Vec::new();
    for (k, m) in modules.iter().enumerate() {
        let mut uses: BTreeMap<String, usize> = BTreeMap::new();
        for f in module_files(&src, m) {
            for (n, c) in references(&code(&std::fs::read_to_string(&f).unwrap()), &modules) {
                *uses.entry(n).or_insert(0) += c;
            }
        }
        uses.remove(m);
        println!("{m} -> {uses:?}");
        for (n, c) in &uses {
            if modules.iter().position(|x| x == n).unwrap() > k {
                upward.push(format!("{m} uses {n} ({c} references), which lib.rs lists after it"));
            }
        }
    }
    assert!(upward.is_empty(), "{upward:#?}");
}

#[test]
fn the_reference_counter_sees_paths_and_groups_but_not_comments() {
    let modules: Vec<String> = ["case", "run"].map(String::from).to_vec();
    let text = code("use crate::{case::Case, run};\n// crate::run::x\nfn f() { crate::case::g() }\n#[cfg(test)]\nmod t { use crate::run; }");
    let r = references(&text, &modules);
    assert_eq!(r.get("case"), Some(&2));
    assert_eq!(r.get("run"), Some(&1));
}
