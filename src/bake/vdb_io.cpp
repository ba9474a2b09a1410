// cambium — .vdb output.
#include "bake/vdb_io.h"

#include "core/error.h"
#include "core/versions.h"

#include <fmt/format.h>
#include <openvdb/io/File.h>


namespace cambium {

void writeVdb(const BakedGrids& grids, const std::string& path, const VdbFileInfo& info)
{
    openvdb::GridPtrVec out;
    for (openvdb::GridBase::Ptr g : {openvdb::GridBase::Ptr(grids.surface),
                                     openvdb::GridBase::Ptr(grids.color),
                                     openvdb::GridBase::Ptr(grids.density)}) {
        if (!g)
            continue;
        g->addStatsMetadata();  // Arnold and others read these
        g->insertMeta("cambium_scene", openvdb::StringMetadata(info.scene));
        g->insertMeta("cambium_voxel_size", openvdb::DoubleMetadata(grids.stats.voxelSize));
        g->insertMeta("cambium_threshold", openvdb::DoubleMetadata(info.threshold));
        g->insertMeta("cambium_half_width", openvdb::DoubleMetadata(info.halfWidth));
        g->insertMeta("cambium_frame", openvdb::Int64Metadata(info.frame));
        g->insertMeta("cambium_time", openvdb::DoubleMetadata(info.time));
        g->insertMeta("cambium_version", openvdb::StringMetadata(version()));
        g->setSaveFloatAsHalf(info.half);
        out.push_back(g);
    }
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(fmt::format("cambium {}", version())));
    if (!info.sequence.empty())
        fileMeta.insertMeta("cambium_sequence", openvdb::StringMetadata(info.sequence));
    writeAtomically(path, [&](const std::string& tmp) {
        openvdb::io::File file(tmp);
        file.setCompression(openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
        file.write(out, fileMeta);
        file.close();
    });
}

std::string readSequenceKey(const std::string& path)
{
    try {
        openvdb::io::File file(path);
        file.open(false);
        const openvdb::MetaMap::Ptr meta = file.getMetadata();
        file.close();
        if (const auto key = meta->getMetadata<openvdb::StringMetadata>("cambium_sequence"))
            return key->value();
    } catch (const std::exception&) {
    }
    return {};
}

}  // namespace cambium
