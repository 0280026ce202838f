//! `crawler-fmu`: writes the text files of the FMUs (used by `scripts/build-fmu.sh`).
//!
//! `crawler-fmu files --fmi 2|3 --out DIR` writes `DIR/modelDescription.xml` and
//! `DIR/documentation/index.html` for the FMI 2.0 or 3.0 FMU, from the defaults the library
//! uses ([`crawler_fmu::defaults`]).

use std::path::PathBuf;
use std::process::ExitCode;

const USAGE: &str = "usage: crawler-fmu files --fmi 2|3 --out DIR";

fn main() -> ExitCode {
    match run(std::env::args().skip(1).collect()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("crawler-fmu: error: {e}\n{USAGE}");
            ExitCode::from(2)
        }
    }
}

fn run(args: Vec<String>) -> Result<(), String> {
    let mut it = args.into_iter();
    match it.next().as_deref() {
        Some("files") => {}
        Some(other) => return Err(format!("unknown command {other:?}")),
        None => return Err("no command".into()),
    }
    let (mut fmi, mut out) = (None, None);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--fmi" => {
                fmi = match it.next().as_deref() {
                    Some("2") => Some(2u8),
                    Some("3") => Some(3u8),
                    v => return Err(format!("invalid --fmi {v:?}: allowed 2 or 3")),
                }
            }
            "--out" => out = it.next().map(PathBuf::from),
            _ => return Err(format!("unknown argument {a:?}")),
        }
    }
    let fmi = fmi.ok_or("--fmi is required")?;
    let out = out.ok_or("--out is required")?;
    let md = crawler_fmu::defaults::model_description();
    let xml = if fmi == 2 {
        md.to_fmi2_xml()
    } else {
        md.to_fmi3_xml()
    };
    let doc = out.join("documentation");
    std::fs::create_dir_all(&doc).map_err(|e| format!("cannot create {}: {e}", doc.display()))?;
    let write = |path: PathBuf, text: String| {
        std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
    };
    write(out.join("modelDescription.xml"), xml)?;
    write(
        doc.join("index.html"),
        crawler_fmu::documentation::index_html(&md, fmi),
    )?;
    Ok(())
}
