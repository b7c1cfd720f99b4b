//! `ribbon init ROBOT.urdf [--floating] [--out FILE | --print]`: writes a first sidecar for a
//! robot that has none ([`crate::starter`]): the box every CAD model has (every link's mass ±5 %,
//! every centre of mass ±2 mm) and a scene worth asking about (the robot holding a pose inside
//! its limits on PD joint controllers, under gravity, limits enforced). Never overwrites a file.

use super::{print_warnings, write_stdout, InitArgs};
use crate::model::{LoadOptions, Model};
use crate::scene::default_sidecar_path;
use crate::starter::StarterScene;
use crate::Error;

/// Runs `ribbon init`.
pub fn run(args: &InitArgs) -> Result<(), Error> {
    let target = args
        .out
        .clone()
        .unwrap_or_else(|| default_sidecar_path(&args.urdf));
    if !args.print {
        if target == args.urdf {
            return Err(Error::BadArgument {
                flag: "--out".to_string(),
                message: format!(
                    "'{}' is the URDF itself; name another file",
                    target.display()
                ),
            });
        }
        if std::fs::symlink_metadata(&target).is_ok() {
            return Err(Error::BadArgument {
                flag: "--out".to_string(),
                message: format!(
                    "'{}' already exists and is not overwritten; edit it, remove it first, name another file with --out FILE, or print the start with --print",
                    target.display()
                ),
            });
        }
    }
    let model = Model::from_urdf_file(
        &args.urdf,
        LoadOptions {
            floating_base: args.floating,
        },
    )?;
    print_warnings(&model);
    let scene = StarterScene::of(&model);
    let robot = args.urdf.file_name().map_or_else(
        || args.urdf.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let text = scene.sidecar_text(&robot);
    if args.print {
        return write_stdout(&text);
    }
    crate::output::paths::write_atomically(&target, "sidecar", text.as_bytes())?;
    eprintln!(
        "init: wrote {} ({} joint controllers, {:.1} s; every link's mass ±5 %, every centre of mass ±2 mm). Next: ribbon analyze {}{}",
        target.display(),
        scene.controllers.len(),
        crate::starter::STARTER_DURATION_S,
        args.urdf.display(),
        if args.out.is_some() {
            format!(" --uncertainty {}", target.display())
        } else {
            String::new()
        }
    );
    Ok(())
}
