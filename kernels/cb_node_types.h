/* cambium — the BlobTree node types, numbered once and for good.
 *
 * One X-macro serves the host (enum, names, JSON type strings) and the
 * kernels (opcodes of the field program).  Never renumber an entry: the
 * numbers end up in compiled field programs and cached kernels.
 *
 * X(IDENT, number, "json type name", kind)   kind: PRIMITIVE | OPERATOR | WARP
 */
#ifndef CAMBIUM_CB_NODE_TYPES_H
#define CAMBIUM_CB_NODE_TYPES_H

#define CB_NODE_TYPES(X)                                        \
    X(SPHERE, 1, "sphere", PRIMITIVE)                           \
    X(SEGMENT, 2, "segment", PRIMITIVE)                         \
    X(CONE, 3, "cone", PRIMITIVE)                               \
    X(CONVOLUTION_SEGMENT, 4, "convolution_segment", PRIMITIVE) \
    X(BLEND, 16, "blend", OPERATOR)                             \
    X(RICCI, 17, "ricci", OPERATOR)                             \
    X(UNION, 18, "union", OPERATOR)                             \
    X(INTERSECTION, 19, "intersection", OPERATOR)               \
    X(DIFFERENCE, 20, "difference", OPERATOR)                   \
    X(PCM, 21, "pcm", OPERATOR)                                 \
    X(GBB, 22, "gbb", OPERATOR)                                 \
    X(BETTER_BLEND, 23, "better_blend", OPERATOR)               \
    X(TRANSFORM, 32, "transform", WARP)                         \
    X(BEND, 33, "bend", WARP)                                   \
    X(TWIST, 34, "twist", WARP)                                 \
    X(TAPER, 35, "taper", WARP)

#define CB_NODE_ENUM_ENTRY(ident, number, name, kind) CB_##ident = number,
enum cb_node_type { CB_NODE_TYPES(CB_NODE_ENUM_ENTRY) CB_NODE_TYPE_END };
#undef CB_NODE_ENUM_ENTRY

#endif /* CAMBIUM_CB_NODE_TYPES_H */
