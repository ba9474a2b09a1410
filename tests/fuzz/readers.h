// cambium fuzzing — each input reader as the fuzzers and the regression test
// drive it: an input is read or refused with an InputError; any other
// exception, a crash, a sanitizer report, or time or memory beyond
// libFuzzer's limits is a finding.
#pragma once

#include "blobtree/scene_io.h"
#include "blobtree/stats.h"
#include "core/error.h"
#include "model/growth.h"
#include "model/growth_params.h"
#include "model/lsystem.h"
#include "model/skeleton.h"
#include "model/tree_builder.h"
#include "model/turtle.h"
#include "io/image_file.h"
#include "io/mesh_file.h"
#include "io/vdb.h"
#include "preview/server.h"
#include "shape/shape.h"
#include "shape/synthesis.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <unistd.h>

namespace cambium::fuzz {

/// A file of this process holding `bytes`, for readers that take a path.
inline std::string asFile(const std::string& bytes, const char* extension)
{
    const char* dir = ::access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    const std::string path =
        std::string(dir) + "/cambium_fuzz_" + std::to_string(::getpid()) + extension;
    if (std::FILE* f = std::fopen(path.c_str(), "wb")) {
        std::fwrite(bytes.data(), 1, bytes.size(), f);
        std::fclose(f);
    }
    return path;
}

/// The readers by harness name; each reads one input.
inline const std::map<std::string, std::function<void(const std::string&)>>& readers()
{
    static const std::map<std::string, std::function<void(const std::string&)>> all = {
        {"scene", [](const std::string& in) { computeStats(parseScene(in, "fuzz.json")); }},
        {"lsystem",
         [](const std::string& in) {
             // The derivation is bounded so that one input's run stays short.
             const LSystem sys = parseLSystem(in, "fuzz.l");
             interpretTurtle(sys, derive(sys, std::min(sys.derivationLength, 8), sys.seed, 20000));
         }},
        {"skeleton",
         [](const std::string& in) {
             const Skeleton sk = parseSkeleton(in, "fuzz.txt");
             if (sk.internodes.size() <= 200)
                 buildTree(sk);
         }},
        {"growth",
         [](const std::string& in) {
             // The internode limit (max_internodes, which bounds the global
             // phase) lowered so that one input's run stays short.
             GrowthParameters p = parseGrowthParameters(in, "fuzz.json");
             p.maxInternodes = std::min(p.maxInternodes, 2e5);
             GrowthModel(p).skeleton(std::min(2.0, double(p.years)), true);
         }},
        {"shape",
         [](const std::string& in) {
             // Parsed whole; synthesised when the base is built in and small,
             // at most 2 levels, so that one input's run stays short (files
             // named in it are read only to be checked).
             ShapeSpec spec = parseShape(in, "fuzz.json");
             const BaseType t = spec.base.type;
             if (t == BaseType::Mesh || t == BaseType::LevelSet || t == BaseType::Model)
                 return;
             const BaseShape base = makeBase(spec.base, spec.source, Device::Cpu);
             if (base.mesh.faceCount() > 256 || allDetails(spec).size() > 4)
                 return;
             ShapeSurface surface(spec, std::min(spec.levels, 2), base);
             surface.synthesize();
             surface.mesh();
         }},
        {"mesh",
         [](const std::string& in) {
             // The first byte picks the format.
             if (in.empty())
                 return;
             const std::string format = in[0] & 1 ? "ply" : "obj";
             std::istringstream s(in.substr(1));
             parseMesh(s, "fuzz." + format, format);
         }},
        {"photo",
         [](const std::string& in) {
             // A bark photo: any format OpenImageIO reads (its header's
             // pixels capped before decoding: here at a million, so that
             // one input's run stays small), made linear RGB.
             readPhoto(asFile(in, ".img"), 1'000'000);
         }},
        {"request",
         [](const std::string& in) {
             // The preview server's bodies (the first byte picks the route):
             // a view edit, or a curve edit applied to a growth file's text
             // by the reader that the server writes the file with.
             if (in.empty())
                 return;
             const std::string body = in.substr(1);
             if (in[0] & 1) {
                 parseViewEdit(body, PreviewView{});
                 return;
             }
             static const std::string growth = [] {
                 std::ifstream f(CAMBIUM_SOURCE_DIR "/examples/populus/populus.json");
                 return std::string(std::istreambuf_iterator<char>(f), {});
             }();
             const CurveEdit edit = parseCurveEdit(body);
             withCurvePoints(growth, "fuzz.json", edit.key, edit.points);
         }},
        {"vdb",
         [](const std::string& in) {
             // mesh's and render's opener, on any file: the structure check
             // walks every tree (each node's blocks the size of its values)
             // before OpenVDB reads it; before that walk, a foreign file's
             // trees could only be read so far (fuzzing them found a heap
             // overflow in OpenVDB 10's io::bloscFromStream, docs/errors.md).
             static const bool initialized = (openvdb::initialize(), true);
             (void)initialized;
             readLevelSet(asFile(in, ".vdb"));
         }},
        {"signedvdb",
         [](const std::string& in) {
             // The same, signed again: cambium's own files past their
             // checksum (which refuses a byte changed anywhere), so that the
             // structure check, OpenVDB's topology reader and the direct
             // leaf decoder (io/leaf_values.cpp) see the damage, as the
             // sweeps' re-signed files did.
             static const bool initialized = (openvdb::initialize(), true);
             (void)initialized;
             std::string bytes = in;
             signVdbAgain(bytes);
             readLevelSet(asFile(bytes, ".vdb"));
         }},
    };
    return all;
}

/// Reads `input` with harness `name`'s reader; an InputError is a refusal,
/// a fine end.
inline void readOrRefuse(const std::string& name, const std::string& input)
{
    try {
        readers().at(name)(input);
    } catch (const InputError&) {
    }
}

}  // namespace cambium::fuzz
