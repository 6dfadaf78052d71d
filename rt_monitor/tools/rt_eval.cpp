// rt_eval: the core on files, for tests and offline replays (not the real-time loop).
//   rt_eval --capacity                                    this build's capacity (capacity.hpp), one `name N` a line
//   rt_eval --coef FILE [--robot NAME] --check
//   rt_eval --coef FILE [--robot NAME] --predict IN OUT   IN rows: q, q̇, q̈, y   OUT: ŷ, e, active, T², T²_s (per sensor)
//   rt_eval --coef FILE [--robot NAME] [--residual acceleration|momentum|combined] --stream IN OUT
//       IN rows: raw q, [the measured q̇, where the file's observer takes it,] y    OUT: ready, q, q̇, q̈, y, ŷ, e, T², T²_s (per sensor), above, in_contact, event,
//       side (per sensor), r, τ_ext, joint (the residual the file selects, or the one named; r is the observer's;
//       combined: T² is s, the outputs the observer's)
// Matrices: "DYMX", int64 rows, int64 cols, then float64 row-major (little-endian). Exit 2 on bad usage or
// data, 10 + LoadError on a refused coefficient file.
#include "rt_monitor/core.hpp"

#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

using namespace dynid::rt;

namespace {

struct Matrix {
    int64_t rows = 0, cols = 0;
    std::vector<double> v;
};

bool read_matrix(const std::string& path, Matrix& m) {
    std::ifstream f(path, std::ios::binary);
    char magic[4];
    if (!f.read(magic, 4) || std::memcmp(magic, "DYMX", 4) != 0) return false;
    if (!f.read(reinterpret_cast<char*>(&m.rows), 8) || !f.read(reinterpret_cast<char*>(&m.cols), 8)) return false;
    if (m.rows < 0 || m.cols < 0 || m.rows * m.cols > (int64_t(1) << 31)) return false;
    m.v.resize(size_t(m.rows * m.cols));
    return bool(f.read(reinterpret_cast<char*>(m.v.data()), std::streamsize(m.v.size() * 8)));
}

bool write_matrix(const std::string& path, const Matrix& m) {
    const std::string tmp = path + ".tmp";
    {
        std::ofstream f(tmp, std::ios::binary);
        f.write("DYMX", 4);
        f.write(reinterpret_cast<const char*>(&m.rows), 8);
        f.write(reinterpret_cast<const char*>(&m.cols), 8);
        f.write(reinterpret_cast<const char*>(m.v.data()), std::streamsize(m.v.size() * 8));
        if (!f) return false;
    }
    return std::rename(tmp.c_str(), path.c_str()) == 0;
}

int usage(const char* msg) {
    std::fprintf(stderr, "rt_eval: error: %s\n", msg);
    return 2;
}

}  // namespace

int main(int argc, char** argv) {
    std::string coef, robot, mode, in, out, residual;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--coef" && i + 1 < argc) coef = argv[++i];
        else if (a == "--robot" && i + 1 < argc) robot = argv[++i];
        else if (a == "--check") mode = "check";
        else if (a == "--capacity") mode = "capacity";
        else if (a == "--residual" && i + 1 < argc) residual = argv[++i];
        else if ((a == "--predict" || a == "--stream") && i + 2 < argc) {
            mode = a.substr(2);
            in = argv[++i];
            out = argv[++i];
        } else return usage(("unknown or incomplete argument '" + a + "'").c_str());
    }
    if (mode == "capacity") {
        std::printf("joints %d\nsensors %d\nbodies %d\nmotors %d\noutputs %d\nwindow %d\neffects %d\nbuses %d\n"
                    "frames %d\nsignals %d\nskins %d\n", kMaxJoints, kMaxSensors, kMaxBodies, kMaxMotors, kMaxOutputs,
                    kMaxWindow, kMaxEffects, kMaxBuses, kMaxFrames, kMaxSignals, kMaxSkins);
        return 0;
    }
    if (coef.empty() || mode.empty()) return usage("need --coef FILE and one of --check, --predict IN OUT, --stream IN OUT");
    auto c = std::make_unique<Coefficients>();
    const LoadResult r = load_coefficients(coef, robot, *c);
    if (!r) {
        std::fprintf(stderr, "rt_eval: refused: %s\n", r.message.c_str());
        return kExitBase + int(r.error);
    }
    const int nj = c->n_joints, no = c->n_outputs, ns = c->n_sensors;
    if (mode == "check") {
        std::printf("ok: %s, %d joints, %d bodies, %d F/T sensors, %d outputs, window %d lag %d, T2_alpha %.6g\n",
                    c->robot_name.c_str(), nj, c->n_bodies, ns, no, c->window, c->lag, c->threshold);
        return 0;
    }
    Matrix x;
    if (!read_matrix(in, x)) return usage(("cannot read matrix " + in).c_str());
    if (!residual.empty() && residual != "acceleration" && residual != "momentum" && residual != "combined")
        return usage(("--residual is acceleration, momentum or combined, not '" + residual + "'").c_str());
    auto core = std::make_unique<Core>(*c);
    const Residual chosen = residual == "momentum"   ? Residual::kMomentum
                            : residual == "combined" ? Residual::kCombined
                                                     : Residual::kAcceleration;
    if (!residual.empty() && !core->set_residual(chosen))
        return usage(("--residual " + residual + ": the coefficient file carries no " +
                      (residual == "momentum" ? "momentum observer" : "combined detector")).c_str());
    Matrix y;
    y.rows = x.rows;
    if (mode == "predict") {
        if (x.cols != 3 * nj + no) return usage("--predict input needs 3·n_joints + n_outputs columns");
        y.cols = 3 * no + 1 + ns;
        y.v.resize(size_t(y.rows * y.cols));
        Prediction p;
        for (int64_t k = 0; k < x.rows; ++k) {
            const double* row = &x.v[size_t(k * x.cols)];
            VecJ q = VecJ::Zero(), dq = VecJ::Zero(), ddq = VecJ::Zero();
            VecO yy = VecO::Zero();
            for (int j = 0; j < nj; ++j) q[j] = row[j], dq[j] = row[nj + j], ddq[j] = row[2 * nj + j];
            for (int i = 0; i < no; ++i) yy[i] = row[3 * nj + i];
            core->predict(q, dq, ddq, yy, p);
            double* o = &y.v[size_t(k * y.cols)];
            for (int i = 0; i < no; ++i) o[i] = p.y_hat[i], o[no + i] = p.e[i], o[2 * no + i] = p.active[i];
            o[3 * no] = p.t2;
            for (int k = 0; k < ns; ++k) o[3 * no + 1 + k] = p.t2_sensor[k];
        }
    } else {
        const int nv = c->measured_velocity ? nj : 0;  // the robot's q̇, where the file's observer takes it
        if (x.cols != nj + nv + no)
            return usage(nv ? "--stream input needs 2·n_joints + n_outputs columns (q, the measured q̇, y)"
                            : "--stream input needs n_joints + n_outputs columns");
        y.cols = 1 + 3 * nj + 3 * no + 4 + 2 * ns + no + nj + 1;
        y.v.resize(size_t(y.rows * y.cols));
        for (int64_t k = 0; k < x.rows; ++k) {
            const double* row = &x.v[size_t(k * x.cols)];
            const Output& s = core->step(row, nv ? row + nj : nullptr, row + nj + nv);
            double* o = &y.v[size_t(k * y.cols)];
            o[0] = s.ready;
            for (int j = 0; j < nj; ++j) o[1 + j] = s.q[j], o[1 + nj + j] = s.dq[j], o[1 + 2 * nj + j] = s.ddq[j];
            double* oo = o + 1 + 3 * nj;
            for (int i = 0; i < no; ++i) oo[i] = s.y[i], oo[no + i] = s.p.y_hat[i], oo[2 * no + i] = s.p.e[i];
            oo += 3 * no;
            oo[0] = s.p.t2;
            for (int k = 0; k < ns; ++k) oo[1 + k] = s.p.t2_sensor[k];
            oo += 1 + ns;
            oo[0] = s.above, oo[1] = s.in_contact, oo[2] = int(s.event);
            for (int k = 0; k < ns; ++k) oo[3 + k] = int(s.side[k]);
            oo += 3 + ns;
            for (int i = 0; i < no; ++i) oo[i] = s.r[i];
            for (int j = 0; j < nj; ++j) oo[no + j] = s.tau_ext[j];
            oo[no + nj] = s.joint;
        }
    }
    if (!write_matrix(out, y)) return usage(("cannot write " + out).c_str());
    return 0;
}
