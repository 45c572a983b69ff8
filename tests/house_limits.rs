//! The house's limits on size and errors (CODE_STYLE.md, "Size and comments" and "Errors").
//! Reads every file under `src/` and fails, naming the file and line, on
//! - a file with more than [`MAX_FILE_LINES`] lines of non-test code (its `#[cfg(test)]` module
//!   does not count: tests beside the code are welcome, and so is a sibling test file);
//! - a function over [`MAX_FUNCTION_LINES`] lines, from `fn` to its closing brace;
//! - a `Result<_, String>` outside the binary's top level (`main.rs`, the files under
//!   `src/cli/`): the library's errors are typed.
//!
//! Test code is left out everywhere: an item under `#[cfg(test)]` or `#[test]`, and a file its
//! parent declares as `#[cfg(test)] mod x;`. What still breaks a limit is listed in
//! [`EXCEPTIONS`]: a new breach fails, and so does a listed one that was fixed, so the list only
//! shrinks.

mod source_scan;

use source_scan::{code_only, tok, tokens};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const MAX_FILE_LINES: usize = 600;
const MAX_FUNCTION_LINES: usize = 120;

/// A limit a file may still break, for now.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Limit {
    /// More than [`MAX_FILE_LINES`] lines of non-test code.
    FileLines,
    /// The named function is over [`MAX_FUNCTION_LINES`] lines.
    Function(&'static str),
    /// This many `Result<_, String>`.
    StringErrors(usize),
}

use Limit::{FileLines, Function, StringErrors};

/// The breaches kept for now. Temporary: drop a line (or lower a count) when one goes; none is
/// left, so a new breach fails.
const EXCEPTIONS: &[(&str, Limit)] = &[];

/// One breach of a limit, where it is.
#[derive(Debug)]
struct Breach {
    file: String,
    line: usize,
    limit: Limit,
    what: String,
}

#[test]
fn files_functions_and_errors_keep_the_limits() {
    let failures = judge(&all_breaches(), EXCEPTIONS);
    assert!(
        failures.is_empty(),
        "the house's limits (CODE_STYLE.md, Size and Errors; tests/house_limits.rs):\n{}",
        failures.join("\n")
    );
}

/// What is wrong with `breaches` against the `exceptions` list: each breach not listed (with
/// its file and line), and each listed one that is fixed (the list must shrink with the code).
fn judge(breaches: &[Breach], exceptions: &[(&str, Limit)]) -> Vec<String> {
    let mut failures = Vec::new();
    // String errors are counted per file; the other limits are one breach each.
    let mut string_errors: BTreeMap<&str, Vec<&Breach>> = BTreeMap::new();
    for b in breaches {
        if let StringErrors(_) = b.limit {
            string_errors.entry(&b.file).or_default().push(b);
        } else if !exceptions.contains(&(b.file.as_str(), b.limit)) {
            failures.push(format!("{}:{}: {}", b.file, b.line, b.what));
        }
    }
    for (file, found) in &string_errors {
        let listed = listed_string_errors(exceptions, file);
        if found.len() > listed {
            failures.extend(
                found
                    .iter()
                    .map(|b| format!("{}:{}: {}", b.file, b.line, b.what)),
            );
            if listed > 0 {
                failures.push(format!(
                    "{file}: {} Result<_, String>, {listed} listed in EXCEPTIONS",
                    found.len()
                ));
            }
        }
    }
    for (file, limit) in exceptions {
        let fixed = match limit {
            StringErrors(listed) => {
                let found = string_errors.get(file).map_or(0, Vec::len);
                (found < *listed)
                    .then(|| format!("{found} Result<_, String>, {listed} listed: lower the count"))
            }
            _ => (!breaches
                .iter()
                .any(|b| b.file == *file && b.limit == *limit))
            .then(|| format!("{limit:?} is within the limit now: drop it from the list")),
        };
        if let Some(fixed) = fixed {
            failures.push(format!("{file}: listed in EXCEPTIONS, {fixed}"));
        }
    }
    failures
}

fn listed_string_errors(exceptions: &[(&str, Limit)], file: &str) -> usize {
    exceptions
        .iter()
        .find_map(|(f, l)| match l {
            StringErrors(n) if *f == file => Some(*n),
            _ => None,
        })
        .unwrap_or(0)
}

#[test]
fn a_new_breach_fails_and_so_does_a_fixed_one_still_listed() {
    let breach = |file: &str, limit| Breach {
        file: file.to_string(),
        line: 7,
        limit,
        what: "what".to_string(),
    };
    let long = breach("src/a.rs", FileLines);
    let errors = [
        breach("src/b.rs", StringErrors(0)),
        breach("src/b.rs", StringErrors(0)),
    ];
    let all: Vec<Breach> = std::iter::once(long).chain(errors).collect();
    let listed = [("src/a.rs", FileLines), ("src/b.rs", StringErrors(2))];
    assert!(judge(&all, &listed).is_empty(), "every breach listed");
    assert_eq!(
        judge(&all, &listed[1..]),
        ["src/a.rs:7: what"],
        "a breach not listed fails with its file and line"
    );
    assert_eq!(
        judge(&all, &[listed[0], ("src/b.rs", StringErrors(1))]),
        [
            "src/b.rs:7: what",
            "src/b.rs:7: what",
            "src/b.rs: 2 Result<_, String>, 1 listed in EXCEPTIONS"
        ],
        "one string error more than listed fails"
    );
    let fixed = judge(&all[1..], &[listed[0], ("src/b.rs", StringErrors(3))]);
    assert_eq!(
        fixed,
        [
            "src/a.rs: listed in EXCEPTIONS, FileLines is within the limit now: drop it from the list",
            "src/b.rs: listed in EXCEPTIONS, 2 Result<_, String>, 3 listed: lower the count"
        ],
        "a fixed breach still listed fails, and so does a count not lowered"
    );
}

/// Every breach of every non-test file under `src/`.
fn all_breaches() -> Vec<Breach> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let files = source_files(&src);
    let mut test_files: Vec<PathBuf> = Vec::new();
    let mut scanned = Vec::new();
    for path in &files {
        let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path:?}: {e}"));
        let scan = scan(&text);
        test_files.extend(scan.test_modules.iter().map(|m| child_module(path, m)));
        scanned.push((path, text, scan));
    }
    let mut breaches = Vec::new();
    for (path, text, scan) in scanned {
        if test_files.iter().any(|t| path.starts_with(t)) {
            continue;
        }
        let rel = path.strip_prefix(&src).unwrap_or(path);
        let file = format!("src/{}", rel.display());
        let binary_top = file == "src/main.rs" || file.starts_with("src/cli/");
        breaches.extend(file_breaches(&file, &text, &scan, binary_top));
    }
    breaches
}

/// The breaches of one file; `binary_top` for the binary's top level, which may use strings
/// as errors.
fn file_breaches(file: &str, text: &str, scan: &Scan, binary_top: bool) -> Vec<Breach> {
    let mut breaches = Vec::new();
    let test_lines: usize = scan.test_items.iter().map(|(a, b)| b - a + 1).sum();
    let lines = text.lines().count().saturating_sub(test_lines);
    if lines > MAX_FILE_LINES {
        breaches.push(Breach {
            file: file.to_string(),
            line: 1,
            limit: FileLines,
            what: format!(
                "{lines} lines of non-test code (limit {MAX_FILE_LINES}): split it along its seams"
            ),
        });
    }
    for f in &scan.functions {
        let length = f.last_line - f.line + 1;
        if length > MAX_FUNCTION_LINES {
            breaches.push(Breach {
                file: file.to_string(),
                line: f.line,
                limit: Function(leak(&f.name)),
                what: format!(
                    "fn {} is {length} lines (limit {MAX_FUNCTION_LINES}): split it into named steps",
                    f.name
                ),
            });
        }
    }
    if !binary_top {
        breaches.extend(scan.string_errors.iter().map(|&line| Breach {
            file: file.to_string(),
            line,
            limit: StringErrors(0),
            what: "Result<_, String>: give it a typed error (thiserror)".to_string(),
        }));
    }
    breaches
}

/// Function names live as long as the test, to compare with the `&'static str` of the list.
fn leak(name: &str) -> &'static str {
    Box::leak(name.to_string().into_boxed_str())
}

/// What one file holds, test code left out.
#[derive(Debug, Default)]
struct Scan {
    /// Items under `#[cfg(test)]` or `#[test]`: first and last line.
    test_items: Vec<(usize, usize)>,
    /// Modules declared `#[cfg(test)] mod x;`, in files of their own.
    test_modules: Vec<String>,
    functions: Vec<FunctionSpan>,
    /// The lines of each `Result<_, String>`.
    string_errors: Vec<usize>,
}

#[derive(Debug)]
struct FunctionSpan {
    name: String,
    line: usize,
    last_line: usize,
}

/// Reads the code of one file (comments and literals blanked).
fn scan(text: &str) -> Scan {
    let tokens = tokens(&code_only(text));
    let mut scan = Scan::default();
    let mut i = 0;
    while i < tokens.len() {
        let line = tokens[i].1;
        if let Some(after) = test_attribute(&tokens, i) {
            let (end, module) = item_end(&tokens, after);
            scan.test_items.push((line, tokens[end].1));
            scan.test_modules.extend(module);
            i = end + 1;
            continue;
        }
        match tokens[i].0.as_str() {
            "fn" if is_ident(tok(&tokens, i + 1)) => {
                if let Some(last_line) = function_end(&tokens, i) {
                    scan.functions.push(FunctionSpan {
                        name: tokens[i + 1].0.clone(),
                        line,
                        last_line,
                    });
                }
            }
            "Result" if tok(&tokens, i + 1) == "<" && error_is_string(&tokens, i + 1) => {
                scan.string_errors.push(line);
            }
            _ => {}
        }
        i += 1;
    }
    scan
}

fn is_ident(t: &str) -> bool {
    t.chars()
        .next()
        .is_some_and(|c| c.is_alphabetic() || c == '_')
}

/// If an attribute `#[test]` or `#[cfg(test)]` (or a `cfg` naming `test` without `not`) starts
/// at `i`, the index of the token after it.
fn test_attribute(tokens: &[(String, usize)], i: usize) -> Option<usize> {
    if tok(tokens, i) != "#" || tok(tokens, i + 1) != "[" {
        return None;
    }
    let end = bracket_end(tokens, i + 1, "[", "]")?;
    let inside: Vec<&str> = tokens[i + 2..end].iter().map(|t| t.0.as_str()).collect();
    let test = inside == ["test"]
        || (inside.first() == Some(&"cfg") && inside.contains(&"test") && !inside.contains(&"not"));
    test.then_some(end + 1)
}

/// The index of the bracket closing the one at `open`.
fn bracket_end(tokens: &[(String, usize)], open: usize, o: &str, c: &str) -> Option<usize> {
    let mut level = 0usize;
    for (j, t) in tokens.iter().enumerate().skip(open) {
        if t.0 == o {
            level += 1;
        } else if t.0 == c {
            level -= 1;
            if level == 0 {
                return Some(j);
            }
        }
    }
    None
}

/// The last token of the item starting at `i` (after its attributes), and the module's name if
/// it is a `mod x;` in a file of its own.
fn item_end(tokens: &[(String, usize)], mut i: usize) -> (usize, Option<String>) {
    while tok(tokens, i) == "#" && tok(tokens, i + 1) == "[" {
        i = bracket_end(tokens, i + 1, "[", "]").map_or(tokens.len(), |e| e + 1);
    }
    let mut depth = 0i32;
    while i < tokens.len() {
        match tokens[i].0.as_str() {
            "(" | "[" => depth += 1,
            ")" | "]" => depth -= 1,
            ";" if depth == 0 => {
                let module = (tok(tokens, i - 2) == "mod").then(|| tokens[i - 1].0.clone());
                return (i, module);
            }
            "{" if depth == 0 => {
                return (
                    bracket_end(tokens, i, "{", "}").unwrap_or(tokens.len() - 1),
                    None,
                );
            }
            _ => {}
        }
        i += 1;
    }
    (tokens.len() - 1, None)
}

/// The last line of the body of the function whose `fn` is at `i`; none for a declaration
/// without a body.
fn function_end(tokens: &[(String, usize)], i: usize) -> Option<usize> {
    let mut depth = 0i32;
    for j in i + 2..tokens.len() {
        match tokens[j].0.as_str() {
            "(" | "[" => depth += 1,
            ")" | "]" => depth -= 1,
            ";" if depth == 0 => return None,
            "{" if depth == 0 => return bracket_end(tokens, j, "{", "}").map(|e| tokens[e].1),
            _ => {}
        }
    }
    None
}

/// Whether the generic arguments opening at `open` (`<`) end with `String`.
fn error_is_string(tokens: &[(String, usize)], open: usize) -> bool {
    let (mut angles, mut parens) = (0i32, 0i32);
    let mut last_arg = open + 1;
    for j in open..tokens.len() {
        match tokens[j].0.as_str() {
            "<" => angles += 1,
            ">" if tok(tokens, j - 1) != "-" && tok(tokens, j - 1) != "=" => {
                angles -= 1;
                if angles == 0 {
                    let arg: Vec<&str> = tokens[last_arg..j].iter().map(|t| t.0.as_str()).collect();
                    return last_arg > open + 1 && arg == ["String"];
                }
            }
            "(" | "[" => parens += 1,
            ")" | "]" => parens -= 1,
            "," if angles == 1 && parens == 0 => last_arg = j + 1,
            ";" | "{" | "}" => return false,
            _ => {}
        }
    }
    false
}

/// The file of module `name` declared in `parent`.
fn child_module(parent: &Path, name: &str) -> PathBuf {
    let dir = parent.parent().unwrap_or(Path::new(""));
    let stem = parent.file_stem().unwrap_or_default();
    let dir = if stem == "mod" || stem == "lib" || stem == "main" {
        dir.to_path_buf()
    } else {
        dir.join(stem)
    };
    let file = dir.join(format!("{name}.rs"));
    if file.exists() {
        file
    } else {
        dir.join(name)
    }
}

/// Every `.rs` file under `src/`.
fn source_files(src: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{dir:?}: {e}"));
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    assert!(
        files.len() > 50,
        "the source files are found: {}",
        files.len()
    );
    files
}

#[test]
fn test_code_functions_and_string_errors_are_found() {
    let text = r#"
fn short() -> Result<(), String> {
    let s = "Result<(), String> in a string";
}
pub fn typed() -> Result<Vec<u8>, MyError> { Ok(vec![]) }
fn nested() -> Option<Result<(u8, String), Box<dyn Fn() -> u8>>> { None }
fn closure() -> Box<dyn Fn() -> Result<u8, String>> { todo!() }
trait T { fn declared(&self) -> Result<(), String>; }
#[cfg(test)]
mod tests;
#[cfg(test)]
mod inline {
    fn helper() -> Result<(), String> {}
}
"#;
    let s = scan(text);
    let names: Vec<(&str, usize, usize)> = s
        .functions
        .iter()
        .map(|f| (f.name.as_str(), f.line, f.last_line))
        .collect();
    assert_eq!(
        names,
        [
            ("short", 2, 4),
            ("typed", 5, 5),
            ("nested", 6, 6),
            ("closure", 7, 7)
        ],
        "functions with bodies outside test code: {names:?}"
    );
    assert_eq!(s.string_errors, [2, 7, 8], "Result<_, String> in code only");
    assert_eq!(s.test_modules, ["tests"]);
    assert_eq!(s.test_items, [(9, 10), (11, 14)]);
}
