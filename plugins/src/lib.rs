pub fn hello(){}
pub mod import;
