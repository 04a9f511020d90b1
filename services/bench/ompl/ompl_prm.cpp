// OMPL's PRM (the C++ library, e.g. Debian libompl-dev) on the same inflated grid as ours, for
// `mentalsim bench prm`. Same input and output as scripts/ompl_prm.py:
//   ompl_prm GRID.pgm JOBS.txt
// GRID.pgm: binary PGM, 255 = the robot may stand in the cell, first image row = top map row.
// JOBS.txt: one job per line: n run seed k resolution_cells start_x start_y goal_x goal_y
//           (grid units: cells, x right, y up, origin at the map's lower-left corner).
// stdout:   n,run,build_ms,search_ms,success,milestones,path   with path "x y;x y;..." in cells.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <ompl/base/ProblemDefinition.h>
#include <ompl/base/SpaceInformation.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/geometric/PathGeometric.h>
#include <ompl/geometric/planners/prm/PRM.h>
#include <ompl/util/Console.h>
#include <ompl/util/RandomNumbers.h>

namespace ob = ompl::base;
namespace og = ompl::geometric;

namespace {

struct Grid {
    int w = 0, h = 0;
    std::vector<unsigned char> free;  // row 0 = bottom row
};

bool read_pgm(const char *path, Grid &g) {
    std::ifstream in(path, std::ios::binary);
    std::string magic;
    int maxval = 0;
    if (!(in >> magic >> g.w >> g.h >> maxval) || magic != "P5" || maxval != 255) return false;
    in.get();  // the single whitespace after the header
    std::vector<unsigned char> img(static_cast<size_t>(g.w) * g.h);
    if (!in.read(reinterpret_cast<char *>(img.data()), img.size())) return false;
    g.free.resize(img.size());
    for (int r = 0; r < g.h; ++r)
        for (int c = 0; c < g.w; ++c)
            g.free[static_cast<size_t>(r) * g.w + c] = img[static_cast<size_t>(g.h - 1 - r) * g.w + c] == 255;
    return true;
}

double ms_since(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

int main(int argc, char **argv) {
    if (argc != 3) {
        std::cerr << "usage: ompl_prm GRID.pgm JOBS.txt\n";
        return 2;
    }
    Grid grid;
    if (!read_pgm(argv[1], grid)) {
        std::cerr << argv[1] << ": not an 8-bit binary PGM\n";
        return 2;
    }
    ompl::msg::setLogLevel(ompl::msg::LOG_WARN);
    std::ifstream jobs(argv[2]);
    std::string line;
    bool seeded = false;
    while (std::getline(jobs, line)) {
        std::istringstream f(line);
        unsigned long n, run, seed, k;
        double res, sx, sy, gx, gy;
        if (!(f >> n >> run >> seed >> k >> res >> sx >> sy >> gx >> gy)) continue;
        if (!seeded) {
            // OMPL's seed must be set before any sampler exists; one seed per process.
            ompl::RNG::setSeed(seed == 0 ? 1 : seed);
            seeded = true;
        }
        auto space = std::make_shared<ob::RealVectorStateSpace>(2);
        ob::RealVectorBounds bounds(2);
        bounds.setLow(0, 0.0);
        bounds.setHigh(0, grid.w);
        bounds.setLow(1, 0.0);
        bounds.setHigh(1, grid.h);
        space->setBounds(bounds);
        auto si = std::make_shared<ob::SpaceInformation>(space);
        const Grid *g = &grid;
        si->setStateValidityChecker([g](const ob::State *s) {
            const double *v = s->as<ob::RealVectorStateSpace::StateType>()->values;
            if (v[0] < 0.0 || v[1] < 0.0) return false;
            const int c = static_cast<int>(v[0]), r = static_cast<int>(v[1]);
            return c < g->w && r < g->h && g->free[static_cast<size_t>(r) * g->w + c] != 0;
        });
        si->setStateValidityCheckingResolution(res / space->getMaximumExtent());
        si->setup();

        ob::ScopedState<> start(space), goal(space);
        start[0] = sx;
        start[1] = sy;
        goal[0] = gx;
        goal[1] = gy;
        auto pdef = std::make_shared<ob::ProblemDefinition>(si);
        pdef->setStartAndGoalStates(start, goal);
        auto prm = std::make_shared<og::PRM>(si);
        prm->setMaxNearestNeighbors(static_cast<unsigned>(k));
        prm->setProblemDefinition(pdef);
        prm->setup();

        auto t0 = std::chrono::steady_clock::now();
        og::PRM *p = prm.get();
        prm->growRoadmap(ob::PlannerTerminationCondition([p, n] { return p->milestoneCount() >= n; }));
        const double build_ms = ms_since(t0);
        auto t1 = std::chrono::steady_clock::now();
        prm->solve(ob::timedPlannerTerminationCondition(2.0));
        const double search_ms = ms_since(t1);
        const bool solved = pdef->hasExactSolution();
        std::string path;
        if (solved) {
            auto *sol = pdef->getSolutionPath()->as<og::PathGeometric>();
            char buf[64];
            for (std::size_t i = 0; i < sol->getStateCount(); ++i) {
                const double *v = sol->getState(i)->as<ob::RealVectorStateSpace::StateType>()->values;
                std::snprintf(buf, sizeof buf, "%s%.6f %.6f", i ? ";" : "", v[0], v[1]);
                path += buf;
            }
        }
        std::printf("%lu,%lu,%.4f,%.4f,%d,%u,%s\n", n, run, build_ms, search_ms, solved ? 1 : 0,
                    prm->milestoneCount(), path.c_str());
        std::fflush(stdout);
    }
    return 0;
}
