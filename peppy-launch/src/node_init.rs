//! `node init`: a new node's folder, as PeppyOS's `node init` lays it out
//! (`node/v1`, the `.peppy/libs` crates or projects, a harness test), with
//! a node that emits and consumes from the first build.

use std::path::{Path, PathBuf};

use crate::cli::{InitArgs, Toolchain};
use crate::error::Result;

/// One file of a new node: where it goes (relative to the node) and its
/// text with `{{name}}`, `{{crate}}` and `{{module}}` still in it.
struct Template {
    path: &'static str,
    text: &'static str,
}

macro_rules! templates {
    ($dir:literal: $($path:literal <- $file:literal),* $(,)?) => {
        &[$(Template {
            path: $path,
            text: include_str!(concat!("../templates/node_init/", $dir, "/", $file)),
        }),*]
    };
}

const CARGO: &[Template] = templates!("cargo":
    "peppy.json5" <- "peppy.json5",
    "Cargo.toml" <- "Cargo.toml",
    ".gitignore" <- "gitignore",
    "src/main.rs" <- "src/main.rs",
    "src/lib.rs" <- "src/lib.rs",
    "tests/harness.rs" <- "tests/harness.rs",
);

const UV: &[Template] = templates!("uv":
    "peppy.json5" <- "peppy.json5",
    "pyproject.toml" <- "pyproject.toml",
    ".gitignore" <- "gitignore",
    "src/{{module}}/__init__.py" <- "__init__.py",
    "src/{{module}}/__main__.py" <- "__main__.py",
    "tests/test_harness.py" <- "tests/test_harness.py",
);

/// Why `node init` made nothing.
#[derive(Debug, thiserror::Error)]
pub enum InitError {
    /// The name is no node name, or no crate or package can be named after
    /// it.
    #[error("`{name}` cannot name a node: {why}")]
    Name {
        /// The name given.
        name: String,
        /// What is wrong with it.
        why: String,
    },
    /// Something is already where the node would go: `init` never
    /// overwrites.
    #[error("{} already exists; `node init` writes only new folders", dir.display())]
    Exists {
        /// The node's folder.
        dir: PathBuf,
    },
    /// A file of the node cannot be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// `peppy-launch node init`: writes the node's folder, then its
/// `.peppy/libs` as `sync` does, and says how to test and run it.
pub(crate) fn run(args: &InitArgs) -> Result {
    let dir = args.to_dir.clone().unwrap_or_default().join(&args.name);
    let written = write_node(&args.name, args.toolchain, &dir)?;
    crate::python_sync::run(&crate::cli::SyncArgs {
        node: dir.clone(),
        repos: Vec::new(),
    })?;
    let shown = dir.display();
    println!(
        "peppy-launch: created node `{}:v1` ({} files) in {shown}",
        args.name, written
    );
    let test = match args.toolchain {
        Toolchain::Cargo => "cargo test".to_string(),
        Toolchain::Uv => {
            // The uv peppy uses (installed for it when none is on PATH),
            // so the line works as printed.
            let uv = crate::python_sync::uv()
                .ok()
                .filter(|uv| crate::python_sync::on_path("uv").as_ref() != Some(uv))
                .map_or_else(|| "uv".to_string(), |uv| uv.display().to_string());
            format!("{uv} run --group dev pytest")
        }
    };
    println!("  test it:  cd {shown} && {test}");
    println!(
        "  run it:   peppy-launch run {shown} --instance-id {}_1",
        crate_name(&args.name)
    );
    Ok(())
}

/// Writes every file of a new node named `name` into `dir`, which must not
/// exist (or be an empty folder). Returns how many files it wrote.
fn write_node(
    name: &str,
    toolchain: Toolchain,
    dir: &Path,
) -> std::result::Result<usize, InitError> {
    check_name(name)?;
    if std::fs::read_dir(dir).is_ok_and(|mut entries| entries.next().is_some())
        || (dir.exists() && !dir.is_dir())
    {
        return Err(InitError::Exists {
            dir: dir.to_path_buf(),
        });
    }
    let module = crate_name(name);
    let fill = |text: &str| {
        text.replace("{{name}}", name)
            .replace("{{crate}}", &module)
            .replace("{{module}}", &module)
    };
    let templates = match toolchain {
        Toolchain::Cargo => CARGO,
        Toolchain::Uv => UV,
    };
    let mut files: Vec<(PathBuf, String)> = templates
        .iter()
        .map(|t| (dir.join(fill(t.path)), fill(t.text)))
        .collect();
    if toolchain == Toolchain::Cargo {
        // The versions peppy is built and tested with, so the node's first
        // build resolves as peppy's does (and offline, where peppy's own
        // build left the crates in cargo's cache). Cargo drops what the
        // node does not use.
        if let Ok(lock) =
            std::fs::read_to_string(crate::rust_libs::peppy_source().join("Cargo.lock"))
        {
            files.push((dir.join("Cargo.lock"), lock));
        }
    }
    for (path, text) in &files {
        let write = || -> std::io::Result<()> {
            if let Some(parent) = path.parent() {
                std::fs::create_dir_all(parent)?;
            }
            std::fs::write(path, text)
        };
        write().map_err(|source| InitError::Write {
            path: path.clone(),
            source,
        })?;
    }
    Ok(files.len())
}

/// A node name `init` can use: a node name (PeppyOS's rule: a letter first,
/// then letters, digits, `_` and `-`) that is also a crate and a Python
/// package once `-` becomes `_`.
fn check_name(name: &str) -> std::result::Result<(), InitError> {
    let refuse = |why: String| InitError::Name {
        name: name.to_string(),
        why,
    };
    peppy_schema::names::check_name(name).map_err(refuse)?;
    if !name.starts_with(|c: char| c.is_ascii_alphabetic()) {
        return Err(refuse("it must start with a letter".into()));
    }
    let module = crate_name(name);
    if peppy_schema::names::is_rust_keyword(&module)
        || peppy_schema::names::is_python_keyword(&module)
    {
        return Err(refuse(format!(
            "`{module}` is a keyword, so no crate or package can be named after it"
        )));
    }
    Ok(())
}

/// The crate (and Python package) a node's code is named: its name with
/// `-` as `_`, as cargo names a crate's library.
fn crate_name(name: &str) -> String {
    name.replace('-', "_")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_cannot_be_a_crate_or_package_are_refused() {
        for bad in ["", "1st", "_x", "my node", "a.b", "while", "fn", "r-#"] {
            assert!(
                matches!(check_name(bad), Err(InitError::Name { .. })),
                "{bad:?}"
            );
        }
        for good in ["hello", "hello_world", "hello-world", "Cam2"] {
            check_name(good).unwrap();
        }
    }

    #[test]
    fn every_placeholder_is_filled() {
        let dir = tempfile::tempdir().unwrap();
        for (toolchain, sub) in [(Toolchain::Cargo, "c"), (Toolchain::Uv, "p")] {
            let node = dir.path().join(sub).join("my-node");
            write_node("my-node", toolchain, &node).unwrap();
            for entry in walkdir::WalkDir::new(&node) {
                let entry = entry.unwrap();
                if entry.file_type().is_file() {
                    let text = std::fs::read_to_string(entry.path()).unwrap();
                    assert!(!text.contains("{{"), "{}", entry.path().display());
                    assert!(!entry.path().display().to_string().contains("{{"));
                }
            }
            assert!(node.join("peppy.json5").is_file());
        }
        assert!(
            dir.path()
                .join("p/my-node/src/my_node/__main__.py")
                .is_file()
        );
    }

    #[test]
    fn an_existing_folder_with_files_is_left_alone() {
        let dir = tempfile::tempdir().unwrap();
        let node = dir.path().join("cam");
        std::fs::create_dir(&node).unwrap();
        std::fs::write(node.join("notes.txt"), "mine").unwrap();
        assert!(matches!(
            write_node("cam", Toolchain::Cargo, &node),
            Err(InitError::Exists { .. })
        ));
        assert_eq!(
            std::fs::read_to_string(node.join("notes.txt")).unwrap(),
            "mine"
        );
        assert!(!node.join("peppy.json5").exists());
    }
}
