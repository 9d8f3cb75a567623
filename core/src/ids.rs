//! Typed ids: `u32` newtypes so that a point, an element, a copy and a cluster can never be mixed up.

macro_rules! id_type {
    ($(#[$m:meta])* $name:ident) => {
        $(#[$m])*
        #[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
        #[repr(transparent)]
        pub struct $name(pub u32);
        impl $name {
            #[inline(always)]
            pub fn idx(self) -> usize { self.0 as usize }
            #[inline(always)]
            pub fn new(i: usize) -> Self { debug_assert!(i <= u32::MAX as usize); Self(i as u32) }
        }
        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result { write!(f, "{}", self.0) }
        }
    };
}

id_type!(
    /// A geometric point of the input mesh (its initial position never changes).
    PointId
);
id_type!(
    /// An element of the mesh (index into the model's element list, in input order).
    ElemId
);
id_type!(
    /// One element's own copy of one of its corner points: `copy = first_copy(elem) + corner`.
    CopyId
);
id_type!(
    /// A set of copies at one point that move as one node: the degree-of-freedom carrier.
    ClusterId
);
id_type!(
    /// An element edge (a pair of points), shared by one or two elements.
    EdgeId
);
id_type!(
    /// An element face of a 3D mesh (three or four points), shared by one or two elements.
    FaceId
);
