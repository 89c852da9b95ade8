//! Unit tests of the selectors, specs and thickness maps.

use super::*;

#[test]
fn specs_parse_print_and_read_back() {
    for s in [
        "indices:1,2,3",
        "file:neck.txt",
        "below:z:0.01",
        "above:x:-0.2",
        "box:0.0,0.0,0.0,1.0,1.0,1.0",
    ] {
        let sel = parse_selector(s).unwrap();
        assert_eq!(parse_selector(&sel.to_string()).unwrap(), sel, "{s}");
    }
    let p = parse_pin("below:y:0.5@250").unwrap();
    assert_eq!(p.stiffness, Some(250.0));
    assert_eq!(parse_pin(&p.to_string()).unwrap(), p);
    for s in [
        "gravity=0,0,-9.81",
        "force=0,0,-1;on=indices:4;per=total;start=0.5;end=1",
        "grab=0,0,0.3;on=above:z:0.09;stiffness=100;end=2",
    ] {
        let l = parse_load(s).unwrap();
        assert_eq!(parse_load(&l.to_string()).unwrap(), l, "{s}");
    }
    for (bad, what) in [
        ("below:w:0", "axis"),
        ("box:1,0,0,0,1,1", "minimum"),
        ("indices:1,x", "vertex index"),
        ("near:1", "selector"),
    ] {
        let e = parse_selector(bad).unwrap_err();
        assert!(e.contains(what), "{bad}: {e}");
    }
    assert!(parse_pin("below:z:0@0").is_err());
    for (bad, what) in [
        ("force=0,0,1", "on="),
        ("grab=0,0,1;on=indices:1", "stiffness"),
        ("gravity=0,0,-9.81;on=indices:1", "every vertex"),
        ("force=0,0;on=indices:1", "3 numbers"),
        ("force=0,0,1;on=indices:1;start=2;end=1", "after start"),
        ("wind=1,2,3", "not a load key"),
    ] {
        let e = parse_load(bad).unwrap_err();
        assert!(e.contains(what), "{bad}: {e}");
    }
    assert_eq!(parse_rule("Z:3e-4:6e-4").unwrap().axis, 2);
    assert!(parse_rule("z:0:1").is_err() && parse_rule("z:1").is_err());
}

#[test]
fn selectors_pick_vertices_and_files_name_their_lines() {
    let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 1.0, 1.0];
    let sel = |s: &str| parse_selector(s).unwrap().select(&x);
    assert_eq!(sel("below:z:0.6").unwrap(), vec![0, 1]);
    assert_eq!(sel("above:y:0.5").unwrap(), vec![2]);
    assert_eq!(sel("box:0,0,0,1,0,1").unwrap(), vec![0, 1]);
    assert_eq!(sel("indices:2,0,2").unwrap(), vec![0, 2]);
    assert!(
        sel("indices:3")
            .unwrap_err()
            .to_string()
            .contains("vertex 3")
    );
    assert!(
        sel("below:z:-1")
            .unwrap_err()
            .to_string()
            .contains("no vertex")
    );
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("g.txt");
    std::fs::write(&f, "# neck\n1\n\n2 # top\n").unwrap();
    let s = Selector::File(f.clone());
    assert_eq!(s.select(&x).unwrap(), vec![1, 2]);
    std::fs::write(&f, "1\none\n").unwrap();
    let e = s.select(&x).unwrap_err().to_string();
    assert!(e.contains("g.txt:2:") && e.contains("one"), "{e}");
    let rel = rewrite_paths("pin", "file:g.txt@5", Some(dir.path()));
    assert_eq!(rel, format!("file:{}@5.0", f.display()));
}

#[test]
fn a_ply_vertex_group_selects_its_nonzero_vertices_and_is_checked() {
    let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 1.0, 1.0];
    let dir = tempfile::tempdir().unwrap();
    let ply = |name: &str, element: &str, values: &[&str]| {
        let path = dir.path().join(name);
        let (vp, fp) = if element == "vertex" {
            ("property float neck\n", "")
        } else {
            ("", "property float neck\n")
        };
        let verts = ["0 0 0", "1 0 0.5", "0 1 1"];
        let mut text = format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\n{vp}element face 1\nproperty list uchar int vertex_indices\n\
             {fp}end_header\n"
        );
        for (i, v) in verts.iter().enumerate() {
            let extra = if element == "vertex" {
                format!(" {}", values[i])
            } else {
                String::new()
            };
            text += &format!("{v}{extra}\n");
        }
        let extra = if element == "face" {
            format!(" {}", values[0])
        } else {
            String::new()
        };
        text += &format!("3 0 1 2{extra}\n");
        std::fs::write(&path, text).unwrap();
        path
    };
    let good = ply("g.ply", "vertex", &["0", "1", "2.5"]);
    let s = parse_selector(&format!("ply:{}:neck", good.display())).unwrap();
    assert_eq!(s.select(&x).unwrap(), vec![1, 2]);
    assert_eq!(parse_selector(&s.to_string()).unwrap(), s, "round trip");
    let err = |sel: String, x: &[f64]| {
        parse_selector(&sel)
            .unwrap()
            .select(x)
            .unwrap_err()
            .to_string()
    };
    assert!(err(format!("ply:{}:tail", good.display()), &x).contains("no vertex has"));
    assert!(
        err(format!("ply:{}:neck", good.display()), &x[..6]).contains("3 vertices, the body 2")
    );
    let face = ply("f.ply", "face", &["1"]);
    assert!(err(format!("ply:{}:neck", face.display()), &x).contains("face property"));
    let none = ply("z.ply", "vertex", &["0", "0", "0"]);
    assert!(err(format!("ply:{}:neck", none.display()), &x).contains("selects no vertex"));
    let e = err(
        format!("ply:{}:neck", dir.path().join("missing.ply").display()),
        &x,
    );
    assert!(e.contains("missing.ply") && e.contains("`neck`"), "{e}");
    assert!(parse_selector("ply:only").is_err());
    let rel = rewrite_paths("pin", "ply:g.ply:neck", Some(dir.path()));
    assert_eq!(rel, format!("ply:{}:neck", good.display()));
}

#[test]
fn thickness_maps_per_face_per_vertex_by_rule_and_checked() {
    let mesh = balloon::mesh::generate::icosphere(1.0, 0).unwrap();
    let (nf, nv) = (mesh.num_triangles(), mesh.num_vertices());
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("t.txt");
    let file = Some(f.as_path());
    let faces: String = (0..nf).map(|i| format!("{}e-4\n", 1 + i % 3)).collect();
    std::fs::write(&f, format!("# per face\n{faces}")).unwrap();
    let t = thickness_map(file, None, "m.obj", &mesh).unwrap().unwrap();
    assert_eq!((t.len(), t[0], t[1]), (nf, 1e-4, 2e-4));
    std::fs::write(&f, "3e-4\n".repeat(nv)).unwrap();
    let t = thickness_map(file, None, "m.obj", &mesh).unwrap().unwrap();
    assert!(t.iter().all(|&h| (h - 3e-4).abs() < 1e-18));
    std::fs::write(&f, "3e-4\n".repeat(nv + 1)).unwrap();
    let e = thickness_map(file, None, "m.obj", &mesh)
        .unwrap_err()
        .to_string();
    assert!(e.contains(&format!("{} values", nv + 1)), "{e}");
    std::fs::write(&f, "3e-4\n-1\n").unwrap();
    let e = thickness_map(file, None, "m.obj", &mesh)
        .unwrap_err()
        .to_string();
    assert!(e.contains("t.txt:2:") && e.contains("-1"), "{e}");
    let rule = Some(parse_rule("z:1e-4:3e-4").unwrap());
    let t = thickness_map(None, rule, "m.obj", &mesh).unwrap().unwrap();
    let (lo, hi) = t
        .iter()
        .fold((1.0f64, 0.0f64), |(a, b), &h| (a.min(h), b.max(h)));
    assert!((lo - 1e-4).abs() < 1e-15 && (hi - 3e-4).abs() < 1e-15);
    assert_eq!(thickness_map(None, None, "m.obj", &mesh).unwrap(), None);
}
