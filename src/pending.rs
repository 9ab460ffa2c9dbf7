//! TEMPORARY (not to be merged): stand-ins for engine readers committed by other
//! engineers later in this session; every one answers "not supported".
use millsim_engine::nc;
pub fn read_cls(_: &str) -> Result<nc::Interpretation, nc::Diagnostics> {
    Err(nc::Diagnostics(vec![nc::Diagnostic::new(1, 1, "APT/CLS files are not supported yet")]))
}
#[derive(serde::Deserialize)]
pub struct StockShape {}
impl StockShape {
    pub fn bounds(&self) -> Result<([f64; 3], [f64; 3]), String> {
        Err("parametric stock is not supported yet".into())
    }
}
pub struct Mesh { pub triangles: Vec<u8> }
impl Mesh {
    pub fn from_stl_bytes(_: &[u8]) -> Result<Mesh, String> { Err("STL is not supported yet".into()) }
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) { ([0.0; 3], [0.0; 3]) }
    pub fn volume(&self) -> f64 { 0.0 }
}
