pub fn hello(){}
pub mod criteria;
pub mod separation;
