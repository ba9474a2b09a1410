// cambium-ptls — the peer program of `cambium bench bake`: what a user of
// OpenVDB writes today to turn a skeleton file into a level set.  Spheres
// along every internode, ParticlesToLevelSet, io::File::write.
//   cambium-ptls SKELETON -o OUT.vdb --voxel-size H [--half-width W]
#include "bench/ptls_peer.h"
#include "core/system.h"
#include "model/skeleton.h"

#include <CLI/CLI.hpp>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <cstdio>
#include <exception>
#include <string>

int main(int argc, char** argv)
{
    std::string input, output;
    double voxelSize = 0.01, halfWidth = 3.0;
    CLI::App app{"ParticlesToLevelSet of a skeleton's internodes, written by io::File::write"};
    app.add_option("skeleton", input, "Skeleton text file")->required();
    app.add_option("-o,--output", output, "Output .vdb file")->required();
    app.add_option("--voxel-size", voxelSize, "Voxel size")->check(CLI::PositiveNumber);
    app.add_option("--half-width", halfWidth, "Narrow-band half-width in voxels")
        ->check(CLI::PositiveNumber);
    CLI11_PARSE(app, argc, argv);
    // (out of memory with grids held ends in an error, not "terminate called")
    cambium::installMemoryReserve();
    try {
        openvdb::initialize();
        const auto spheres = cambium::internodeSpheres(cambium::loadSkeleton(input));
        openvdb::FloatGrid::Ptr grid = cambium::ptlsLevelSet(spheres, voxelSize, halfWidth);
        grid->setName("surface");
        openvdb::io::File file(output);
        file.write({grid});
        file.close();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "cambium-ptls: %s\n", e.what());
        return 1;
    }
    return 0;
}
