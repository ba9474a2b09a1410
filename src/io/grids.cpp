// cambium — the grid types cambium makes, compiled once (io/grids.h says why).
#include "io/grids.h"

template class openvdb::tree::Tree<openvdb::FloatTree::RootNodeType>;
template class openvdb::tree::Tree<openvdb::Vec3fTree::RootNodeType>;
template class openvdb::Grid<openvdb::FloatTree>;
template class openvdb::Grid<openvdb::Vec3fTree>;
