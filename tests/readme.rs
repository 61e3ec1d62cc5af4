//! The case-file reference in README.md and the parser cannot drift apart: the README's example
//! case parses and validates with the parser, every key that a shipped case uses is documented
//! in the reference, and so is every field the parser accepts in every table (read from the
//! parser's own "expected one of ..." list for an unknown key, so a new schema field without
//! documentation fails here).

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

/// The field names the parser accepts in a table: the "expected one of ..." list of the error
/// that an unknown key in it gives.
fn accepted_fields(snippet: &str) -> Vec<String> {
    let e = Case::from_toml_str(snippet, "probe.toml").map(|_| ()).unwrap_err().to_string();
    let list = e.split("expected one of ").nth(1).or_else(|| e.split("expected ").nth(1)).unwrap_or_else(|| panic!("{snippet}: {e}"));
    list.split('`').skip(1).step_by(2).map(String::from).collect()
}

#[test]
fn every_field_the_parser_accepts_is_documented() {
    const UNKNOWN: &str = "bogus_key = 1";
    let mut tables: Vec<String> = [
        "",
        "[physics]",
        "[fluid]",
        "[time]",
        "[solver]",
        "[solver.newton]",
        "[[boundary]]",
        "[output]",
        "[output.slice]",
        "[[output.probe]]",
        "[[output.boundary_integral]]",
        "[[output.profile]]",
        "[[output.combination]]",
        "[solid]",
        "[[solid.boundary]]",
        "[solid.loading]",
        "[solid.fibres]",
        "[[solid.contact]]",
    ]
    .iter()
    .map(|t| format!("title = \"t\"\n{t}\n{UNKNOWN}\n"))
    .collect();
    for kind in ["rectangle", "channel", "box", "pipe", "gmsh"] {
        tables.push(format!("title = \"t\"\n[mesh]\nkind = \"{kind}\"\n{UNKNOWN}\n"));
    }
    for kind in ["rectangle", "quadrilateral", "box", "gmsh"] {
        tables.push(format!("title = \"t\"\n[solid]\nmesh = {{ kind = \"{kind}\", {UNKNOWN} }}\n"));
    }
    tables.push(format!("title = \"t\"\n[[boundary]]\nname = \"a\"\ntype = \"windkessel\"\nwindkessel = {{ {UNKNOWN} }}\n"));
    for kind in ["ramp", "sine", "quarter-sine-hold", "table"] {
        tables.push(format!("title = \"t\"\n[[boundary]]\nname = \"a\"\ntype = \"free\"\ntime_function = {{ kind = \"{kind}\", {UNKNOWN} }}\n"));
    }
    let reference = readme_case_section();
    let mut missing = Vec::new();
    for snippet in &tables {
        let fields = accepted_fields(snippet);
        assert!(!fields.is_empty(), "{snippet}");
        for f in fields {
            // A key (`f =`, `` `f` ``) or a table (`[f]`, `[[x.f]]`, `[f.x]`).
            let forms = [format!("{f} ="), format!("`{f}`"), format!("[{f}]"), format!(".{f}]"), format!("[{f}.")];
            if !forms.iter().any(|form| reference.contains(form.as_str())) {
                missing.push(format!("{f} (in {:?})", snippet.lines().nth(1).unwrap_or("")));
            }
        }
    }
    assert!(missing.is_empty(), "fields the parser accepts but README's case-file reference does not document: {missing:?}");
}

/// Every shipped case's header says what `tests/cases.rs` checks (a `# Check` line), as the
/// README's table of built-in cases promises.
#[test]
fn every_case_header_has_a_checks_line() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let header: Vec<&str> = text.lines().take_while(|l| l.starts_with('#')).collect();
        assert!(
            header.iter().any(|l| l.starts_with("# Check") && l.contains("tests/")),
            "{}: the header has no '# Check(s) (tests/...)' line",
            path.display()
        );
    }
}

/// The numbers the tests hold (tests/cases.rs and the others assert each of them, as an
/// independent reference or a regression value) as they are printed in README.md and in the
/// case's header: when a value moves, its test fails, and this test fails until the README and
/// the header print the new value.
const PUBLISHED: &[(&str, &[&str])] = &[
    ("schaefer-turek-2d1", &["144 788", "5.579470", "0.0106317", "0.117865", "1.2e-5"]),
    ("womersley-axisymmetric", &["0.11 %"]),
    ("cylinder-re100", &["0.2982", "3.2174", "0.954"]),
    ("model-problem-1", &["0.34 downstream", "0.12 up", "1.6 %", "4.4 %", "3e-15", "29 679"]),
    ("model-problem-2", &["2e-9", "2.6e-3", "28 %"]),
    ("model-problem-3", &["0.104689", "0.104680", "7 927", "1.1e-8", "5.8e-6", "8e-6", "1.2e-2"]),
    ("model-problem-4", &["0.104418", "0.53 %", "0.26 %", "75 018", "1.1e-7", "9e-8", "2.4e-5", "4.8e-4", "8.7e-3"]),
    ("model-problem-4-fine", &["0.104584", "0.89 %", "0.10 %", "143 922", "6e-7", "9e-7", "6.9e-5", "3.3e-4", "3.9e-4", "9.1e-3"]),
    ("cook-membrane", &["6.889"]),
    ("cylinder-inflation-axisymmetric", &["4e-7"]),
    ("turek-hron-csm1", &["7.187", "66.10", "7.1573", "65.945", "0.42 %", "0.24 %"]),
    ("turek-hron-csm2", &["0.4690", "16.97", "0.46695", "16.932", "0.44 %", "0.22 %"]),
    ("turek-hron-cfd1", &["14.29", "1.119", "14.3032", "1.12761", "0.09 %", "0.77 %"]),
    (
        "turek-hron-fsi1",
        &[
            "660 593", "536 s", "0.022714", "0.80999", "14.2575", "0.76624", "0.0227", "0.8209", "14.295", "0.7638", "1.33 %", "0.26 %", "0.76639",
            "0.84920",
        ],
    ),
    ("turek-hron-cfd2", &["136.7", "10.53", "136.721", "10.5480", "0.015 %", "0.17 %"]),
    ("turek-hron-cfd3", &["439.45", "5.6183", "11.893", "437.81", "4.3956", "439.61", "5.625", "11.03", "436.56", "4.4173", "7.3 %"]),
    ("turek-hron-fsi2", &["45 041", "1.21", "77.04", "1.9375", "204.12", "4.4 %", "3.1 %", "2.3 %", "169 762", "1.18", "80.67", "1.9347", "209.80"]),
    (
        "turek-hron-fsi3",
        &["44 993", "1.35", "32.04", "5.467", "449.24", "6.8 %", "3.1 %", "1.8 %", "32.09", "5.469", "169 828", "1.42", "34.18", "5.481", "460.88"],
    ),
    ("fluid-film", &["4807.29", "4811.4", "4712.4", "0.086 %", "2.0 %"]),
    ("turek-hron-csm3", &["14.305", "63.607", "65.160", "1.0995", "14.375", "14.374", "64.176", "64.690", "0.89 %"]),
];

#[test]
fn published_numbers_appear_in_the_readme_and_the_case_headers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    for (case, numbers) in PUBLISHED {
        let text = std::fs::read_to_string(root.join("cases").join(format!("{case}.toml"))).unwrap();
        let header: String = text.lines().take_while(|l| l.starts_with('#')).collect::<Vec<_>>().join(" ");
        // The header wraps lines: compare with runs of spaces and '#' folded to one space.
        let fold = |s: &str| s.replace('#', " ").split_whitespace().collect::<Vec<_>>().join(" ");
        let (header, readme) = (fold(&header), fold(&readme));
        for n in *numbers {
            assert!(readme.contains(n), "README.md does not print {n} ({case})");
            assert!(header.contains(n), "cases/{case}.toml's header does not print {n}");
        }
    }
}
