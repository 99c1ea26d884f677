//! Checks on the files a command will write, made before any work: an output is never an
//! existing file unless `--force` says so, never a folder, never in a folder that cannot be
//! written, and never one of the command's inputs, whatever the flags (a trace turned into
//! an MCAP by `--record mine.csv --force` is lost).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

/// An input of a command: a file (or a folder whose files are all inputs) and the option or
/// argument that named it, for messages.
#[derive(Clone, Copy, Debug)]
pub struct Input<'a> {
    pub path: &'a Path,
    pub option: &'a str,
}

impl<'a> Input<'a> {
    pub fn new(path: &'a Path, option: &'a str) -> Self {
        Input { path, option }
    }
}

/// Refuses an output path before any work: one that is an input (always), one that exists
/// (unless `force`), one that is a folder, or one whose folder is missing or not writable,
/// naming the file and the option.
pub fn check_output_of(path: &Path, force: bool, option: &str, inputs: &[Input]) -> Result<()> {
    check_not_input(path, option, inputs)?;
    check_output(path, force, option)
}

/// [`check_output_of`] for a command without file inputs.
pub fn check_output(path: &Path, force: bool, option: &str) -> Result<()> {
    let shown = path.display();
    if path.is_dir() {
        bail!("{shown}: {option}: is a folder; expected a file name");
    }
    if path.exists() {
        if !force {
            bail!(
                "{shown}: {option}: the file exists; pass --force to overwrite it, or choose \
                 another name"
            );
        }
        std::fs::OpenOptions::new()
            .append(true)
            .open(path)
            .with_context(|| format!("{shown}: {option}: cannot be overwritten"))?;
        return Ok(());
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    check_writable_dir(dir).with_context(|| format!("{shown}: {option}: cannot be written"))
}

/// Refuses an output that is one of the inputs, or a file of an input folder: by name once
/// both are made absolute and resolved, and by device and inode, so that a hard link or a
/// symbolic link to the input is caught too. `--force` does not lift this.
pub fn check_not_input(output: &Path, option: &str, inputs: &[Input]) -> Result<()> {
    for input in inputs {
        let files: Vec<PathBuf> = if input.path.is_dir() {
            std::fs::read_dir(input.path)
                .map(|entries| entries.filter_map(|e| e.ok().map(|e| e.path())).collect())
                .unwrap_or_default()
        } else {
            vec![input.path.to_path_buf()]
        };
        if let Some(file) = files.iter().find(|f| same_file(output, f)) {
            let what = if file.as_path() == input.path {
                String::new()
            } else {
                format!(" ({} in that folder)", file.display())
            };
            bail!(
                "{}: {option}: this is the input {} ({}){what}; an output may never overwrite \
                 an input, even with --force: choose another name",
                output.display(),
                input.option,
                input.path.display()
            );
        }
    }
    Ok(())
}

/// Two outputs of one command that name the same file would be written twice.
pub fn check_distinct(a: Option<&Path>, b: Option<&Path>, what: &str) -> Result<()> {
    if let (Some(a), Some(b)) = (a, b) {
        if same_file(a, b) {
            bail!("{}: {what} name the same file", a.display());
        }
    }
    Ok(())
}

/// Whether two paths are one file: equal once made absolute with `.` and `..` and symbolic
/// links resolved (as far as they exist), or the same device and inode.
pub fn same_file(a: &Path, b: &Path) -> bool {
    if a == b || resolved(a) == resolved(b) {
        return true;
    }
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(ma), Ok(mb)) => same_inode(&ma, &mb),
        _ => false,
    }
}

#[cfg(unix)]
fn same_inode(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
fn same_inode(_: &std::fs::Metadata, _: &std::fs::Metadata) -> bool {
    false
}

/// The path made absolute, its existing part canonicalised (symbolic links followed) and
/// the part that does not exist yet appended as written.
fn resolved(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut tail = Vec::new();
    let mut head = absolute.as_path();
    loop {
        if let Ok(real) = head.canonicalize() {
            return tail.iter().rev().fold(real, |p: PathBuf, c| p.join(c));
        }
        match (head.parent(), head.file_name()) {
            (Some(parent), Some(name)) => {
                tail.push(name.to_os_string());
                head = parent;
            }
            _ => return absolute,
        }
    }
}

/// Refuses an output folder a command fills with files before any work, by the rule every
/// output follows: hexcue creates the output itself (a file, or this folder) but never the
/// folders above it, so a mistyped path is refused rather than created. The folder may exist
/// (and must then be writable), or its parent must.
pub fn check_output_dir(dir: &Path, option: &str) -> Result<()> {
    let shown = dir.display();
    if dir.exists() {
        if !dir.is_dir() {
            bail!("{shown}: {option}: is a file; expected a folder");
        }
        return check_writable_dir(dir)
            .with_context(|| format!("{shown}: {option}: cannot be written"));
    }
    let parent = match dir.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    check_writable_dir(parent).with_context(|| format!("{shown}: {option}: cannot be created"))
}

/// Creates the output folder [`check_output_dir`] accepted (its last part only).
pub fn create_output_dir(dir: &Path, option: &str) -> Result<()> {
    if dir.is_dir() {
        return Ok(());
    }
    std::fs::create_dir(dir)
        .with_context(|| format!("{}: {option}: cannot create the folder", dir.display()))
}

/// A folder exists and a file can be created in it (tried, then removed).
pub fn check_writable_dir(dir: &Path) -> Result<()> {
    if !dir.is_dir() {
        bail!("the folder {} does not exist", dir.display());
    }
    let probe = dir.join(format!(".hexcue-write-check-{}", std::process::id()));
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => bail!("cannot create a file in the folder {}: {e}", dir.display()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_input_is_never_an_output_by_any_name() {
        let dir = tempfile::tempdir().unwrap();
        let trace = dir.path().join("mine.csv");
        std::fs::write(&trace, "t,fx\n").unwrap();
        let sub = dir.path().join("sub");
        std::fs::create_dir(&sub).unwrap();
        let dotted = sub.join("..").join("mine.csv");
        let hard = dir.path().join("hard.csv");
        std::fs::hard_link(&trace, &hard).unwrap();
        let inputs = [Input::new(&trace, "--trace")];
        for name in [&trace, &dotted, &hard] {
            for force in [false, true] {
                let e = check_output_of(name, force, "--record", &inputs).unwrap_err();
                let m = e.to_string();
                assert!(
                    m.contains("--record") && m.contains("--trace") && m.contains("mine.csv"),
                    "{m}"
                );
                assert!(m.contains(&name.display().to_string()), "{m}");
            }
        }
        #[cfg(unix)]
        {
            let link = dir.path().join("link.csv");
            std::os::unix::fs::symlink(&trace, &link).unwrap();
            assert!(check_output_of(&link, true, "--summary", &inputs).is_err());
        }
        // Another file, existing or new, is as before.
        let other = dir.path().join("other.mcap");
        check_output_of(&other, false, "--record", &inputs).unwrap();
        std::fs::write(&other, "x").unwrap();
        assert!(check_output_of(&other, false, "--record", &inputs).is_err());
        check_output_of(&other, true, "--record", &inputs).unwrap();
    }

    #[test]
    fn a_file_of_an_input_folder_is_an_input() {
        let dir = tempfile::tempdir().unwrap();
        let trace = dir.path().join("a.csv");
        std::fs::write(&trace, "t\n").unwrap();
        let inputs = [Input::new(dir.path(), "--traces")];
        let m = check_output_of(&trace, true, "--out", &inputs)
            .unwrap_err()
            .to_string();
        assert!(m.contains("--traces") && m.contains("a.csv"), "{m}");
        check_output_of(&dir.path().join("report.md"), true, "--out", &inputs).unwrap();
    }

    #[test]
    fn relative_and_absolute_names_of_a_new_file_are_one_file() {
        let cwd = std::env::current_dir().unwrap();
        let rel = Path::new("no-such-dir-hexcue/x.json");
        assert!(same_file(rel, &cwd.join("no-such-dir-hexcue/./x.json")));
        assert!(!same_file(rel, &cwd.join("no-such-dir-hexcue/y.json")));
        let e = check_distinct(Some(rel), Some(&cwd.join(rel)), "--record and --summary");
        assert!(e.is_err());
    }

    #[test]
    fn outputs_are_checked_before_the_work() {
        let dir = tempfile::tempdir().unwrap();
        let existing = dir.path().join("run.mcap");
        std::fs::write(&existing, "precious").unwrap();
        let e = check_output(&existing, false, "--record").unwrap_err();
        let m = format!("{e:#}");
        assert!(m.contains("run.mcap") && m.contains("--force"), "{m}");
        check_output(&existing, true, "--record").unwrap();
        assert_eq!(std::fs::read_to_string(&existing).unwrap(), "precious");

        let missing_dir = dir.path().join("nope").join("x.json");
        let m = format!(
            "{:#}",
            check_output(&missing_dir, false, "--summary").unwrap_err()
        );
        assert!(m.contains("x.json") && m.contains("does not exist"), "{m}");
        let m = format!("{:#}", check_output(dir.path(), false, "-o").unwrap_err());
        assert!(m.contains("is a folder"), "{m}");
        check_output(&dir.path().join("new.json"), false, "--summary").unwrap();
        // The probe leaves nothing behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
