//! Every shipped scene loads, and its grid can be made.

use std::path::PathBuf;

use stride_footstep::grid::Grid;
use stride_footstep::scene::Scene;

#[test]
fn every_shipped_scene_loads_and_rasterises() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/scenes");
    let mut n = 0;
    for dir in ["archie", "kaist", "lola"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(root.join(dir))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        files.sort();
        assert!(!files.is_empty(), "{dir}");
        for f in files {
            let s = Scene::load(&f).unwrap_or_else(|e| panic!("{e}"));
            assert!(s.name.starts_with(dir), "{}: {}", f.display(), s.name);
            let g = Grid::of_scene(&s).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            assert!(g.contains(s.start.p()), "{}", s.name);
            n += 1;
        }
    }
    // 11 Archie cases, the KAIST scenarios, LOLA's six.
    assert!(n >= 11 + 18 + 6, "{n}");
}

#[test]
fn a_bad_scene_says_what_is_wrong() {
    let dir = std::env::temp_dir();
    let bad = |text: &str| Scene::parse(text, &dir).unwrap_err().to_string();
    let base = "name = \"x\"\nstart = { x = 0.0, y = 0.0 }\ngoal = { x = 1.0, y = 0.0 }\n";
    assert!(bad(&format!(
        "{base}[[surface]]\npoints = [[0.0, 0.0], [1.0, 0.0]]\nheight = 0.1\n"
    ))
    .contains("surface 1 has 2 corners"));
    assert!(bad(&format!(
        "{base}[[surface]]\npoints = [[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]]\nheight = 0.1\n"
    ))
    .contains("not convex and counter-clockwise"));
    assert!(bad(&format!("{base}[[obstacle]]\nshape = \"cone\"\n")).contains("cone"));
    let s = Scene::parse(
        &format!("{base}[map]\nx = [-1.0, 1.0]\ny = [-1.0, 1.0]\nelevation = \"missing.csv\"\n"),
        &dir,
    )
    .unwrap();
    assert!(Grid::of_scene(&s)
        .unwrap_err()
        .to_string()
        .contains("missing.csv"));
}

#[test]
fn an_elevation_file_reads_top_row_first() {
    let dir = std::env::temp_dir().join(format!("stride-elev-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // 2 rows of 3 cells of 0.5 m: the first line is the row of greatest y.
    std::fs::write(
        dir.join("e.csv"),
        "# heights\n0.1, 0.2, nan\n0.0, 0.0, 0.3\n",
    )
    .unwrap();
    let s = Scene::parse(
        "name = \"x\"\nstart = { x = 0.2, y = 0.2 }\ngoal = { x = 1.2, y = 0.2 }\n\
         [map]\nx = [0.0, 1.5]\ny = [0.0, 1.0]\nresolution = 0.5\nelevation = \"e.csv\"\n",
        &dir,
    )
    .unwrap();
    let g = Grid::of_scene(&s).unwrap();
    assert_eq!(g.height(stride_footstep::geom::v2(0.2, 0.7)), 0.1);
    assert_eq!(g.height(stride_footstep::geom::v2(1.2, 0.2)), 0.3);
    assert!(g.height(stride_footstep::geom::v2(1.2, 0.7)).is_nan());
    std::fs::write(dir.join("e.csv"), "0.1, 0.2\n0.0, 0.0\n").unwrap();
    let e = Grid::of_scene(&s).unwrap_err().to_string();
    assert!(e.contains("2 columns; the map's extent needs 3"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_clockwise_polygon_is_an_obstacle_all_the_same() {
    let s = Scene::parse(
        "name = \"x\"\nstart = { x = 0.0, y = 0.0 }\ngoal = { x = 3.0, y = 0.0 }\n\
         [[obstacle]]\nshape = \"polygon\"\npoints = [[1.0, 1.0], [2.0, 1.0], [2.0, -1.0], [1.0, -1.0]]\n\
         height = 1.0\n",
        &std::env::temp_dir(),
    )
    .unwrap();
    let g = Grid::of_scene(&s).unwrap();
    assert_eq!(g.height(stride_footstep::geom::v2(1.5, 0.0)), 1.0);
}
