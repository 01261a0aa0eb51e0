#include "cutter/PathFile.h"

#include "vdb/Error.h"

#include <glm/geometric.hpp>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <istream>
#include <ostream>
#include <sstream>

namespace mtcut::cutter {

namespace {

constexpr const char* kFieldNames[8] = {"t", "x", "y", "z", "dx", "dy", "dz", "length"};

std::string_view trim(std::string_view s)
{
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
        s.remove_suffix(1);
    return s;
}

[[noreturn]] void fail(const std::string& source, size_t line, const std::string& what)
{
    throw InputError(source + ":" + std::to_string(line) + ": " + what);
}

bool isHeader(std::string_view s)
{
    // "t,x,y,z,dx,dy,dz,length", spaces around fields allowed.
    size_t field = 0;
    while (true) {
        const size_t comma = s.find(',');
        const std::string_view f = trim(s.substr(0, comma));
        if (field >= 8 || f != kFieldNames[field]) return false;
        ++field;
        if (comma == std::string_view::npos) break;
        s.remove_prefix(comma + 1);
    }
    return field == 8;
}

} // namespace

PathLine parsePathLine(std::string_view raw, size_t lineNumber, const std::string& source)
{
    PathLine out;
    const std::string_view s = trim(raw);
    if (s.empty() || s == "stroke") {
        out.kind = PathLine::Kind::StrokeBreak;
        return out;
    }
    if (s.front() == '#') return out;
    if (s == "end") {
        out.kind = PathLine::Kind::End;
        return out;
    }
    if (s.front() == 't' && isHeader(s)) return out;

    double v[8];
    size_t field = 0;
    std::string_view rest = s;
    while (true) {
        const size_t comma = rest.find(',');
        const std::string_view f = trim(rest.substr(0, comma));
        if (field >= 8)
            fail(source, lineNumber,
                 "expected 8 fields (t,x,y,z,dx,dy,dz,length), found more");
        const std::string name = kFieldNames[field];
        if (f.empty()) fail(source, lineNumber, "field " + name + ": empty");
        const std::string text(f);
        char* end = nullptr;
        errno = 0;
        const double d = std::strtod(text.c_str(), &end);
        if (end != text.c_str() + text.size())
            fail(source, lineNumber, "field " + name + ": '" + text + "' is not a number");
        if (!std::isfinite(d) || errno == ERANGE)
            fail(source, lineNumber, "field " + name + ": '" + text + "' is not a finite number");
        v[field++] = d;
        if (comma == std::string_view::npos) break;
        rest.remove_prefix(comma + 1);
    }
    if (field != 8)
        fail(source, lineNumber,
             "expected 8 fields (t,x,y,z,dx,dy,dz,length), found " + std::to_string(field) +
                 " (truncated line?); field " + kFieldNames[field] + " missing");
    // Positions and lengths past a kilometre are no pose of a saw in a scan,
    // and squared they would overflow the voxeliser's doubles.
    for (size_t i : {1, 2, 3, 7})
        if (std::abs(v[i]) > kMaxPoseMm) {
            std::ostringstream m;
            m << "field " << kFieldNames[i] << ": " << v[i] << " mm is out of range (at most " << kMaxPoseMm
              << (i == 7 ? " mm)" : " mm from the origin)");
            fail(source, lineNumber, m.str());
        }
    out.kind = PathLine::Kind::Pose;
    out.pose.time = v[0];
    out.pose.base = glm::dvec3(v[1], v[2], v[3]);
    out.pose.direction = glm::dvec3(v[4], v[5], v[6]);
    out.pose.length = v[7];
    return out;
}

void checkPose(Pose& pose, size_t lineNumber, const std::string& source)
{
    if (!(pose.length > 0.0)) fail(source, lineNumber, "field length: blade length must be > 0 mm");
    const double l = glm::length(pose.direction);
    if (!(l >= 1e-9) || !std::isfinite(l))
        fail(source, lineNumber, "field dx,dy,dz: direction is zero");
    pose.direction /= l;
}

std::vector<std::vector<Pose>> readPath(std::istream& in, const std::string& source)
{
    std::vector<std::vector<Pose>> strokes(1);
    std::string line;
    size_t lineNumber = 0;
    while (std::getline(in, line)) {
        ++lineNumber;
        PathLine pl = parsePathLine(line, lineNumber, source);
        if (pl.kind == PathLine::Kind::End) break;
        if (pl.kind == PathLine::Kind::Skip) continue;
        if (pl.kind == PathLine::Kind::StrokeBreak) {
            if (!strokes.back().empty()) strokes.emplace_back();
            continue;
        }
        checkPose(pl.pose, lineNumber, source);
        if (!strokes.back().empty() && pl.pose.time < strokes.back().back().time) {
            std::ostringstream s;
            s << "field t: time goes backwards (" << pl.pose.time << " s after "
              << strokes.back().back().time << " s)";
            fail(source, lineNumber, s.str());
        }
        strokes.back().push_back(pl.pose);
    }
    if (in.bad()) fail(source, lineNumber, "read error");
    if (strokes.back().empty()) strokes.pop_back();
    return strokes;
}

std::vector<std::vector<Pose>> readPathFile(const std::string& path)
{
    std::ifstream in(path);
    if (!in) throw InputError(path + ": cannot open path file");
    return readPath(in, path);
}

std::string formatPoseLine(const Pose& p)
{
    std::ostringstream s;
    s << std::setprecision(17) << p.time << ',' << p.base.x << ',' << p.base.y << ','
      << p.base.z << ',' << p.direction.x << ',' << p.direction.y << ',' << p.direction.z << ','
      << p.length;
    return s.str();
}

void writePath(std::ostream& out, const std::vector<std::vector<Pose>>& strokes)
{
    out << "t,x,y,z,dx,dy,dz,length\n";
    for (size_t i = 0; i < strokes.size(); ++i) {
        if (i) out << "stroke\n";
        for (const Pose& p : strokes[i]) out << formatPoseLine(p) << '\n';
    }
}

} // namespace mtcut::cutter
