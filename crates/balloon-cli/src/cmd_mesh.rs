//! `balloon mesh info <FILE|builtin[:NAME]> [--json]`: statistics and validity of a mesh.

use anyhow::{Context, Result};
use balloon_mesh::geometry;
use balloon_mesh::topology::Topology;
use balloon_mesh::validate::{ValidationOptions, validate};
use balloon_run::output::print_json_line;
use serde::Serialize;
use std::io::Write;

/// Mesh subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum MeshCommand {
    /// Print mesh statistics: counts, topology (closed, manifold, orientation, genus), surface
    /// area, enclosed volume, bounding box and minimum angle.
    Info(InfoArgs),
}

/// Arguments of `balloon mesh info`.
#[derive(Debug, clap::Args)]
pub struct InfoArgs {
    /// Mesh file (.obj, .off, .ply, .stl) or `builtin[:NAME]` (teddy, icosphere, sphere,
    /// octasphere, uvsphere, torus, box, tube, fin, teddy-coarse).
    pub mesh: String,
    /// Print the statistics as one JSON object on the last stdout line.
    #[arg(long)]
    pub json: bool,
}

/// What `balloon mesh info` reports (the JSON object of `--json`). Lengths in the mesh's units
/// (metres for built-ins).
#[derive(Debug, Serialize)]
pub struct MeshInfo {
    /// The mesh spec as given.
    pub mesh: String,
    /// Vertex count.
    pub vertices: usize,
    /// Triangle count.
    pub triangles: usize,
    /// Unique edge count.
    pub edges: usize,
    /// Edge-connected components.
    pub components: usize,
    /// Every edge has exactly two triangles.
    pub closed: bool,
    /// No non-manifold edge or vertex.
    pub manifold: bool,
    /// Neighbouring triangles traverse shared edges in opposite directions.
    pub consistently_oriented: bool,
    /// Every closed component encloses a positive volume.
    pub outward: bool,
    /// Genus (closed orientable manifolds only, else null).
    pub genus: Option<usize>,
    /// Euler characteristic V - E + F.
    pub euler_characteristic: i64,
    /// Total surface area.
    pub surface_area: f64,
    /// Enclosed volume by the divergence theorem (Wang et al. 2015, Eq. 13).
    pub enclosed_volume: f64,
    /// Bounding box minimum corner.
    pub bbox_min: [f64; 3],
    /// Bounding box maximum corner.
    pub bbox_max: [f64; 3],
    /// Smallest triangle angle, degrees.
    pub min_angle_degrees: Option<f64>,
    /// Number of defects found by validation (0: ready to simulate).
    pub defects: usize,
    /// The first defect, if any.
    pub first_defect: Option<String>,
}

/// Computes the [`MeshInfo`] of the mesh named by `spec`.
pub fn mesh_info(spec: &str) -> Result<MeshInfo> {
    let mesh = balloon_mesh::load(spec).with_context(|| format!("cannot load mesh `{spec}`"))?;
    let rep = validate(&mesh, &ValidationOptions::default());
    let topo = Topology::new(&mesh);
    let bb = geometry::bounding_box(&mesh);
    let corner = |p: Option<nalgebra::Point3<f64>>| p.map_or([f64::NAN; 3], |p| [p.x, p.y, p.z]);
    Ok(MeshInfo {
        mesh: spec.to_string(),
        vertices: mesh.num_vertices(),
        triangles: mesh.num_triangles(),
        edges: topo.num_edges(),
        components: rep.components,
        closed: rep.closed,
        manifold: rep.manifold,
        consistently_oriented: rep.consistently_oriented,
        outward: rep.outward,
        genus: rep.genus,
        euler_characteristic: topo.euler_characteristic(),
        surface_area: geometry::surface_area(&mesh),
        enclosed_volume: geometry::enclosed_volume(&mesh),
        bbox_min: corner(bb.map(|b| b.min)),
        bbox_max: corner(bb.map(|b| b.max)),
        min_angle_degrees: geometry::min_angle_degrees(&mesh),
        defects: rep.defects.len(),
        first_defect: rep.defects.first().map(ToString::to_string),
    })
}

/// Runs a mesh subcommand.
pub fn run(cmd: MeshCommand) -> Result<()> {
    match cmd {
        MeshCommand::Info(args) => {
            let info = mesh_info(&args.mesh)?;
            if args.json {
                print_json_line(&info)?;
            } else {
                let mut out = std::io::stdout().lock();
                let w = &mut out;
                let yn = |b: bool| if b { "yes" } else { "no" };
                writeln!(w, "mesh:                  {}", info.mesh)?;
                writeln!(w, "vertices:              {}", info.vertices)?;
                writeln!(w, "triangles:             {}", info.triangles)?;
                writeln!(w, "edges:                 {}", info.edges)?;
                writeln!(w, "components:            {}", info.components)?;
                writeln!(w, "closed:                {}", yn(info.closed))?;
                writeln!(w, "manifold:              {}", yn(info.manifold))?;
                writeln!(
                    w,
                    "consistently oriented: {}",
                    yn(info.consistently_oriented)
                )?;
                writeln!(w, "outward:               {}", yn(info.outward))?;
                match info.genus {
                    Some(g) => writeln!(w, "genus:                 {g}")?,
                    None => writeln!(
                        w,
                        "genus:                 undefined (not a closed orientable manifold)"
                    )?,
                }
                writeln!(w, "surface area:          {:.6e}", info.surface_area)?;
                writeln!(w, "enclosed volume:       {:.6e}", info.enclosed_volume)?;
                writeln!(
                    w,
                    "bounding box:          [{:.6}, {:.6}, {:.6}] .. [{:.6}, {:.6}, {:.6}]",
                    info.bbox_min[0],
                    info.bbox_min[1],
                    info.bbox_min[2],
                    info.bbox_max[0],
                    info.bbox_max[1],
                    info.bbox_max[2]
                )?;
                match info.min_angle_degrees {
                    Some(a) => writeln!(w, "minimum angle:         {a:.3} deg")?,
                    None => writeln!(w, "minimum angle:         n/a")?,
                }
                match &info.first_defect {
                    None => writeln!(w, "defects:               none (ready to simulate)")?,
                    Some(d) => writeln!(w, "defects:               {} (first: {d})", info.defects)?,
                }
                w.flush()?;
            }
            Ok(())
        }
    }
}
