//! `crawler run --controller-cmd "COMMAND"`: any external controller (a Python script with
//! `softcrawler`, a program in another language) started by the launcher in the controller's
//! place, with the launcher's checks and the recorder.
//!
//! The command is split into words like a shell does (single and double quotes, backslash
//! escapes; no variables, globs or pipes) and started directly, not through a shell. The launcher
//! appends the run's network flags, the ones every controller of the project takes:
//! `--run-id ID` and `--credential PATH` (or `--no-auth`), then the arguments after `--`.

use std::path::{Path, PathBuf};

use crate::children::{Auth, Invocation};

/// The words of `command`, split as a shell would (quotes and backslashes; nothing else is
/// special). An unclosed quote or a command without words is refused.
pub fn split_command(command: &str) -> anyhow::Result<Vec<String>> {
    let refuse = |why: &str| {
        anyhow::anyhow!("invalid --controller-cmd = {command:?}: allowed a command line ({why})")
    };
    let mut words = Vec::new();
    let mut word: Option<String> = None;
    let mut chars = command.chars();
    while let Some(c) = chars.next() {
        match c {
            c if c.is_whitespace() => {
                if let Some(w) = word.take() {
                    words.push(w);
                }
            }
            '\'' => {
                let w = word.get_or_insert_with(String::new);
                loop {
                    match chars.next() {
                        Some('\'') => break,
                        Some(c) => w.push(c),
                        None => return Err(refuse("a single quote is not closed")),
                    }
                }
            }
            '"' => {
                let w = word.get_or_insert_with(String::new);
                loop {
                    match chars.next() {
                        Some('"') => break,
                        Some('\\') => match chars.next() {
                            Some(c) => w.push(c),
                            None => return Err(refuse("a backslash ends it")),
                        },
                        Some(c) => w.push(c),
                        None => return Err(refuse("a double quote is not closed")),
                    }
                }
            }
            '\\' => match chars.next() {
                Some(c) => word.get_or_insert_with(String::new).push(c),
                None => return Err(refuse("a backslash ends it")),
            },
            c => word.get_or_insert_with(String::new).push(c),
        }
    }
    words.extend(word);
    if words.is_empty() {
        return Err(refuse("it has no words"));
    }
    Ok(words)
}

/// The program named by `word`: a path (with a `/`) that is a file, or a file of that name on
/// `PATH`.
pub fn find_program(word: &str) -> anyhow::Result<PathBuf> {
    let missing = || {
        anyhow::anyhow!(
            "invalid --controller-cmd program = {word:?}: allowed an executable file (a path, or a name on PATH)"
        )
    };
    if word.contains('/') {
        let p = Path::new(word);
        return if p.is_file() {
            Ok(p.to_path_buf())
        } else {
            Err(missing())
        };
    }
    std::env::var_os("PATH")
        .iter()
        .flat_map(std::env::split_paths)
        .map(|d| d.join(word))
        .find(|p| p.is_file())
        .ok_or_else(missing)
}

/// The external controller of run `run_id`: `command`'s program and words, the run's network
/// flags, then `extra`.
pub fn invocation(
    command: &str,
    run_id: &str,
    auth: &Auth,
    extra: &[String],
) -> anyhow::Result<Invocation> {
    let words = split_command(command)?;
    let exe = find_program(&words[0])?;
    let mut args: Vec<String> = words[1..].to_vec();
    args.extend(["--run-id".into(), run_id.into()]);
    args.extend(auth.args());
    args.extend(extra.iter().cloned());
    Ok(Invocation { exe, args })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_command_splits_into_words_as_a_shell_splits_it() {
        let w = split_command(r#".venv/bin/python  'my dir/ctl.py' --gain "0.5" a\ b"#).unwrap();
        assert_eq!(
            w,
            [".venv/bin/python", "my dir/ctl.py", "--gain", "0.5", "a b"]
        );
        assert!(split_command("python 'open").is_err());
        assert!(split_command("   ").is_err());
    }

    #[test]
    fn the_external_controller_gets_the_runs_flags_after_its_own() {
        let auth = Auth::Credential("/run/c".into());
        let inv = invocation("sh -c true", "r1", &auth, &["--x".into()]).unwrap();
        assert!(inv.exe.ends_with("sh"), "{inv:?}");
        assert_eq!(
            inv.args,
            [
                "-c",
                "true",
                "--run-id",
                "r1",
                "--credential",
                "/run/c",
                "--x"
            ]
        );
        let open = invocation("sh", "r2", &Auth::Open, &[]).unwrap();
        assert_eq!(open.args, ["--run-id", "r2", "--no-auth"]);
        let e = invocation("no-such-program-here", "r", &Auth::Open, &[]).unwrap_err();
        assert!(e.to_string().contains("--controller-cmd"), "{e}");
    }
}
