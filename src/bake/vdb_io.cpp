// cambium — .vdb output.
#include "bake/vdb_io.h"

#include "core/error.h"
#include "core/versions.h"

#include <fmt/format.h>
#include <openvdb/io/File.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>

namespace cambium {

std::string temporaryPathFor(const std::string& path)
{
    return fmt::format("{}.tmp-{}", path, ::getpid());
}

void checkWritable(const std::string& path)
{
    const std::string tmp = temporaryPathFor(path);
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
    if (fd < 0)
        throw InputError(fmt::format("{}: cannot write the output: {}", path, std::strerror(errno)));
    ::close(fd);
    ::unlink(tmp.c_str());
}

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
    const std::string tmp = temporaryPathFor(path);
    try {
        openvdb::io::File file(tmp);
        file.setCompression(openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
        file.write(out, fileMeta);
        file.close();
    } catch (const std::exception& e) {
        ::unlink(tmp.c_str());
        throw InputError(fmt::format("{}: cannot write the output: {}", path, e.what()));
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const std::string why = std::strerror(errno);
        ::unlink(tmp.c_str());
        throw InputError(fmt::format("{}: cannot write the output: {}", path, why));
    }
}

}  // namespace cambium
