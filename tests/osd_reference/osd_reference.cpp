// Reference Catmull-Clark refinement and limit evaluation with OpenSubdiv Far.
//
// Test-only program of seatkit: the test suite compiles it against the
// system OpenSubdiv (libosd-dev, -losdCPU) and compares seatkit's sparse
// operators with its output. Reads a cage from stdin:
//
//   boundary <0 = edge-and-corner | 1 = edge-only>
//   levels <L>
//   vertices <nv>        then nv lines "x y z"
//   faces <nf>           then nf lines "k v0 v1 ... v(k-1)"
//   creases <nc>         then nc lines "a b sharpness"
//   corners <nk>         then nk lines "v sharpness"
//
// For each level l = 1..L it refines a fresh refiner uniformly to l
// (double precision PrimvarRefiner) and writes
//
//   level <l> <points> <faces>
//   p x y z              refined points (Interpolate), OpenSubdiv order
//   f a b c d            faces of level l
//   q x y z tx ty tz sx sy sz   Limit position and both tangents
//
// with 17 significant digits.
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

using namespace OpenSubdiv;

struct Point {
    double x[3];
    void Clear() { x[0] = x[1] = x[2] = 0.0; }
    void AddWithWeight(Point const& src, double w) {
        x[0] += w * src.x[0];
        x[1] += w * src.x[1];
        x[2] += w * src.x[2];
    }
};

static bool expect(std::istream& in, const char* word, int& value) {
    std::string tag;
    if (!(in >> tag >> value) || tag != word) {
        std::fprintf(stderr, "expected '%s <int>'\n", word);
        return false;
    }
    return true;
}

int main() {
    int boundary = 0, levels = 1, nv = 0, nf = 0, nc = 0, nk = 0;
    if (!expect(std::cin, "boundary", boundary) || !expect(std::cin, "levels", levels)) return 2;
    if (!expect(std::cin, "vertices", nv)) return 2;
    std::vector<Point> cage(nv);
    for (int i = 0; i < nv; ++i) std::cin >> cage[i].x[0] >> cage[i].x[1] >> cage[i].x[2];
    if (!expect(std::cin, "faces", nf)) return 2;
    std::vector<int> sizes(nf), indices;
    for (int i = 0; i < nf; ++i) {
        std::cin >> sizes[i];
        for (int k = 0; k < sizes[i]; ++k) {
            int v;
            std::cin >> v;
            indices.push_back(v);
        }
    }
    if (!expect(std::cin, "creases", nc)) return 2;
    std::vector<int> creasePairs(2 * nc);
    std::vector<float> creaseWeights(nc);
    for (int i = 0; i < nc; ++i) std::cin >> creasePairs[2 * i] >> creasePairs[2 * i + 1] >> creaseWeights[i];
    if (!expect(std::cin, "corners", nk)) return 2;
    std::vector<int> cornerVerts(nk);
    std::vector<float> cornerWeights(nk);
    for (int i = 0; i < nk; ++i) std::cin >> cornerVerts[i] >> cornerWeights[i];
    if (!std::cin) {
        std::fprintf(stderr, "malformed input\n");
        return 2;
    }

    Far::TopologyDescriptor desc;
    desc.numVertices = nv;
    desc.numFaces = nf;
    desc.numVertsPerFace = sizes.data();
    desc.vertIndicesPerFace = indices.data();
    desc.numCreases = nc;
    desc.creaseVertexIndexPairs = nc ? creasePairs.data() : nullptr;
    desc.creaseWeights = nc ? creaseWeights.data() : nullptr;
    desc.numCorners = nk;
    desc.cornerVertexIndices = nk ? cornerVerts.data() : nullptr;
    desc.cornerWeights = nk ? cornerWeights.data() : nullptr;

    Sdc::Options options;
    options.SetVtxBoundaryInterpolation(boundary == 0 ? Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER
                                                      : Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);

    for (int level = 1; level <= levels; ++level) {
        typedef Far::TopologyRefinerFactory<Far::TopologyDescriptor> Factory;
        Far::TopologyRefiner* refiner =
            Factory::Create(desc, Factory::Options(Sdc::SCHEME_CATMARK, options));
        if (!refiner) {
            std::fprintf(stderr, "TopologyRefinerFactory failed\n");
            return 3;
        }
        Far::TopologyRefiner::UniformOptions uniform(level);
        uniform.fullTopologyInLastLevel = true;  // Limit() needs the last level's full topology
        refiner->RefineUniform(uniform);

        std::vector<Point> buffer(refiner->GetNumVerticesTotal());
        for (int i = 0; i < nv; ++i) buffer[i] = cage[i];
        Far::PrimvarRefinerReal<double> primvar(*refiner);
        Point* src = buffer.data();
        for (int l = 1; l <= level; ++l) {
            Point* dst = src + refiner->GetLevel(l - 1).GetNumVertices();
            primvar.Interpolate(l, src, dst);
            src = dst;
        }
        Far::TopologyLevel const& last = refiner->GetLevel(level);
        int np = last.GetNumVertices();
        std::vector<Point> pos(np), tan1(np), tan2(np);
        primvar.Limit(src, pos, tan1, tan2);

        std::printf("level %d %d %d\n", level, np, last.GetNumFaces());
        for (int i = 0; i < np; ++i)
            std::printf("p %.17g %.17g %.17g\n", src[i].x[0], src[i].x[1], src[i].x[2]);
        for (int f = 0; f < last.GetNumFaces(); ++f) {
            Far::ConstIndexArray fv = last.GetFaceVertices(f);
            std::printf("f");
            for (int k = 0; k < fv.size(); ++k) std::printf(" %d", fv[k]);
            std::printf("\n");
        }
        for (int i = 0; i < np; ++i)
            std::printf("q %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", pos[i].x[0], pos[i].x[1],
                        pos[i].x[2], tan1[i].x[0], tan1[i].x[1], tan1[i].x[2], tan2[i].x[0], tan2[i].x[1],
                        tan2[i].x[2]);
        delete refiner;
    }
    return 0;
}
