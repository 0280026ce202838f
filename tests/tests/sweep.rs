//! `crawler sweep`: the launcher runs a plan with figures; the map's recording reads back with
//! Rerun's own reader, its tensors shaped and named after the plan's axes.

use std::process::Command;

use crawler_e2e::{bin, repo_root};

#[test]
fn crawler_sweep_runs_a_plan_and_records_the_map_with_named_axes() {
    let sweep_bin = bin("crawler-sweep"); // built next to `crawler`, which runs it
    assert!(sweep_bin.is_file());
    let dir = tempfile::tempdir().unwrap();
    let plan = dir.path().join("tiny.toml");
    std::fs::write(
        &plan,
        format!(
            "name = \"tiny\"\nscenario = {:?}\n[set]\nnumerics.cells = 32\nnumerics.settle = 1.5\nnumerics.t_end = 3.0\n\
             [[axes]]\nkey = \"actuation.k\"\nvalues = [6.283185307179586, 12.566370614359172]\n\
             [[axes]]\nkey = \"friction.eps\"\nvalues = [0.0, 0.5, 1.0]\n\
             [[axes]]\nkey = \"actuation.alpha\"\nvalues = [0.5, 0.9, 1.1, 1.5]\n\
             [evaluate]\nplant = true\nmodels = [\"paper\", \"improved\"]\n\
             [figures]\nx = \"actuation.alpha\"\ny = \"friction.eps\"\nrows = \"actuation.k\"\n",
            repo_root().join("scenarios/paper.toml").display().to_string()
        ),
    )
    .unwrap();
    let out = Command::new(bin("crawler"))
        .args([
            "sweep",
            plan.to_str().unwrap(),
            "--out",
            "tiny.parquet",
            "--store",
            "store",
            "--figures-dir",
            "fig",
        ])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("24 points, 0 stored, 24 to run"), "{err}");
    assert!(dir.path().join("tiny.parquet").is_file());
    assert!(dir.path().join("fig/tiny-paper-worst.png").is_file());

    use rerun::dataframe::external::re_chunk_store::{ChunkStore, ChunkStoreConfig};
    let file = std::fs::File::open(dir.path().join("fig/tiny.rrd")).unwrap();
    let stores = ChunkStore::from_rrd_reader(
        &ChunkStoreConfig::ALL_DISABLED,
        &mut std::io::BufReader::new(file),
    )
    .unwrap();
    let data = rerun::Tensor::descriptor_data().component;
    let mut tensors = std::collections::BTreeMap::new();
    let mut paths = Vec::new();
    for store in stores.values() {
        for chunk in store.iter_physical_chunks() {
            let path = chunk
                .entity_path()
                .to_string()
                .trim_start_matches('/')
                .to_string();
            paths.push(path.clone());
            if let Some(Ok(batch)) = chunk.component_batch::<rerun::components::TensorData>(data, 0)
            {
                tensors.insert(path, batch[0].0.clone());
            }
        }
    }
    for p in ["axes", "figures/tiny-paper-worst", "plant/stuck_fraction"] {
        assert!(paths.iter().any(|x| x == p), "{p} not in {paths:?}");
    }
    let v = &tensors["maps/paper/velocity"];
    assert_eq!(v.shape(), &[2, 3, 4], "rows (k) x y (eps) x x (alpha)");
    let names: Vec<String> = (0..3).map(|i| v.dim_name(i).unwrap().to_string()).collect();
    assert_eq!(names, ["actuation.k", "friction.eps", "actuation.alpha"]);
    // percent errors; at eps = 0 the paper's power is the exact linear one (within 2 % at N = 64)
    let p = &tensors["maps/paper/power"];
    let rerun::datatypes::TensorBuffer::F32(values) = &p.buffer else {
        panic!("f32 tensor")
    };
    for ix in 0..4 {
        assert!(
            values[ix].abs() < 2.0,
            "eps = 0, alpha #{ix}: {} %",
            values[ix]
        );
    }
}
