// cambium — the float grid type cambium makes, compiled once (io/grids.h says
// why; the Vec3f grid is io/grids_vec3f.cpp, so that the two compile at once).
#include "io/grids.h"

template class openvdb::tree::Tree<openvdb::FloatTree::RootNodeType>;
template class openvdb::Grid<openvdb::FloatTree>;
