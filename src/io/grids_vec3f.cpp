// cambium — the Vec3f grid type cambium makes, compiled once (io/grids.h).
#include "io/grids.h"

template class openvdb::tree::Tree<openvdb::Vec3fTree::RootNodeType>;
template class openvdb::Grid<openvdb::Vec3fTree>;
