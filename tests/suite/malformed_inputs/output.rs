//! Files and folders the tool writes: a full disk, an output folder under a file or on a
//! read-only file system, a failed command after its claim.

use super::*;
use relight_cpc::import::mesh::Mesh;
use relight_cpc::out_dir::OutDir;
use relight_cpc::sphere::envmap::LatLong;

#[test]
fn disk_full_while_writing_a_mesh_is_a_clear_error() {
    // /dev/full accepts the open and fails every write with ENOSPC.
    let dev = Path::new("/dev/full");
    if !dev.exists() {
        eprintln!("skipped: no /dev/full on this system");
        return;
    }
    let (mesh, _) = Mesh::from_parts(
        vec![
            relight_cpc::Vec3::zeros(),
            relight_cpc::Vec3::x(),
            relight_cpc::Vec3::y(),
        ],
        vec![[0, 1, 2]],
    );
    let msg = plain(mesh.write_ply(dev, &[]).unwrap_err().to_string(), dev);
    assert!(msg.contains("No space left"), "{msg}");
}

#[test]
fn disk_full_while_writing_a_map_is_a_clear_error() {
    let dev = Path::new("/dev/full");
    if !dev.exists() {
        eprintln!("skipped: no /dev/full on this system");
        return;
    }
    let msg = plain(
        LatLong::black(4).write_exr(dev).unwrap_err().to_string(),
        dev,
    );
    assert!(msg.contains("No space left"), "{msg}");
}

// ---------------------------------------------------------------- output folders (library)

#[test]
fn out_folder_under_a_file_is_refused_before_any_work() {
    // The folder cannot exist: its parent is a file (works as root, unlike chmod).
    let (_d, f) = file("out-under-file", "notes.txt", b"mine");
    let out = f.join("result");
    let msg = OutDir::claim(&out, true, &[], "test")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("is a file"), "{msg}");
    assert_eq!(std::fs::read(&f).unwrap(), b"mine");
}

#[test]
fn out_folder_on_a_read_only_file_system_is_refused() {
    // sysfs refuses new folders even to root (EPERM), like a read-only mount.
    let sys = Path::new("/sys");
    if !sys.is_dir() {
        eprintln!("skipped: no /sys on this system");
        return;
    }
    let out = sys.join("relight-cpc-result");
    let msg = OutDir::claim(&out, false, &[], "test")
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("cannot write in /sys") && msg.contains("permission denied"),
        "{msg}"
    );
}

#[test]
fn out_folder_error_leaves_the_previous_result_untouched() {
    // A command that fails after the claim (its staging folder dropped) leaves the old
    // result as it was and no staging folder beside it.
    let d = scratch("malformed", "out-fail");
    let out = d.join("res");
    let c = OutDir::claim(&out, false, &[], "test").unwrap();
    std::fs::write(c.path().join("a.txt"), "old").unwrap();
    c.commit().unwrap();
    let before = snapshot(&d);
    {
        let c = OutDir::claim(&out, true, &[], "test").unwrap();
        std::fs::write(c.path().join("a.txt"), "half-written").unwrap();
        // dropped without commit: the command failed
    }
    assert_eq!(snapshot(&d), before);
}
