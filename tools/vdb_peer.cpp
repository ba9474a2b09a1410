// cambium-vdbpeer — what `cambium bench read` sets cambium's commands
// against: what a user of OpenVDB (or of cambium's library) writes today to
// open a baked frame.
//   cambium-vdbpeer read FILE [GRID]   io::File, every grid (or GRID) read whole
//   cambium-vdbpeer mesh FILE [GRID]   io::File (delayed loading, its default) and volumeToMesh
//   cambium-vdbpeer cambium FILE       cambium's reader (readLevelSet): surface and Cd
#include "core/system.h"
#include "io/vdb.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <cstdio>
#include <exception>
#include <string>

int main(int argc, char** argv)
{
    if (argc < 3) {
        std::fprintf(stderr, "usage: cambium-vdbpeer read|mesh|cambium FILE [GRID]\n");
        return 64;
    }
    const std::string mode = argv[1], path = argv[2], grid = argc > 3 ? argv[3] : "";
    // (out of memory with grids held ends in an error, not "terminate called")
    cambium::installMemoryReserve();
    try {
        openvdb::initialize();
        size_t voxels = 0;
        if (mode == "read") {
            openvdb::io::File file(path);
            file.open(false);
            if (grid.empty()) {
                const openvdb::GridPtrVecPtr grids = file.getGrids();
                for (const auto& g : *grids)
                    voxels += g->activeVoxelCount();
            } else {
                voxels = file.readGrid(grid)->activeVoxelCount();
            }
        } else if (mode == "mesh") {
            openvdb::io::File file(path);
            file.open();
            const auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(
                file.readGrid(grid.empty() ? "surface" : grid));
            std::vector<openvdb::Vec3s> points;
            std::vector<openvdb::Vec3I> triangles;
            std::vector<openvdb::Vec4I> quads;
            openvdb::tools::volumeToMesh(*g, points, triangles, quads, 0.0, 0.0);
            voxels = points.size();
        } else if (mode == "cambium") {
            const cambium::LevelSetGrids g = cambium::readLevelSet(path);
            voxels = g.surface->activeVoxelCount() + (g.color ? g.color->activeVoxelCount() : 0);
        } else {
            std::fprintf(stderr, "cambium-vdbpeer: unknown mode '%s'\n", mode.c_str());
            return 64;
        }
        std::printf("%zu\n", voxels);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "cambium-vdbpeer: %s\n", e.what());
        return 1;
    }
    return 0;
}
