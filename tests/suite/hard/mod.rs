//! Hard cases: extreme and degenerate inputs render a right, finite image or are refused
//! before any allocation, with a message that names the file and the field.

mod hard_cases;
mod hard_extremes;
