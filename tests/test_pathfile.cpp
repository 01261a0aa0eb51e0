// The path format parser (cutter/PATH_FORMAT.md): strokes, comments, the
// column header, and errors that name the line and the field.
#include "cutter/PathFile.h"
#include "vdb/Error.h"

#include <gtest/gtest.h>

#include <random>
#include <sstream>

#include <glm/geometric.hpp>

using namespace mtcut::cutter;

namespace {

std::vector<std::vector<Pose>> parse(const std::string& text)
{
    std::istringstream in(text);
    return readPath(in, "cut.path");
}

/// The error message of parsing `text`, or "" when it parses.
std::string errorOf(const std::string& text)
{
    try {
        parse(text);
    } catch (const mtcut::InputError& e) {
        return e.what();
    }
    return "";
}

} // namespace

TEST(PathFile, ExampleFromTheIssue)
{
    const auto s = parse("# comment lines start with '#'\n"
                         "t,x,y,z,dx,dy,dz,length\n"
                         "0.000,120.5,98.0,1100.0,0,0,-1,30\n");
    ASSERT_EQ(s.size(), 1u);
    ASSERT_EQ(s[0].size(), 1u);
    const Pose& p = s[0][0];
    EXPECT_EQ(p.time, 0.0);
    EXPECT_EQ(p.base, glm::dvec3(120.5, 98.0, 1100.0));
    EXPECT_EQ(p.direction, glm::dvec3(0, 0, -1));
    EXPECT_EQ(p.length, 30.0);
}

TEST(PathFile, StrokesCommentsHeaderWhitespaceCrlf)
{
    const auto s = parse("t, x, y, z, dx, dy, dz, length\r\n"
                         "0,1,2,3,0,0,2,10\r\n"
                         "  0.5 , 1.5,2,3, 0,0,1 ,10  \n"
                         "\n"
                         "\n"
                         "# between strokes\n"
                         "1,0,0,0,3,4,0,5\n"
                         "stroke\n"
                         "stroke\n"
                         "0.25,0,0,0,1,0,0,1\n"
                         "2.5e-1,0,0,0,1,0,0,1"); // no final newline; equal time is fine
    ASSERT_EQ(s.size(), 3u);
    EXPECT_EQ(s[0].size(), 2u);
    EXPECT_EQ(s[0][0].direction, glm::dvec3(0, 0, 1)); // normalised
    EXPECT_EQ(s[0][1].time, 0.5);
    ASSERT_EQ(s[1].size(), 1u);
    EXPECT_NEAR(s[1][0].direction.x, 0.6, 1e-15);
    EXPECT_NEAR(s[1][0].direction.y, 0.8, 1e-15);
    EXPECT_EQ(s[2].size(), 2u);
    EXPECT_EQ(s[2][0].time, 0.25); // time may restart in a new stroke
}

TEST(PathFile, ErrorsNameLineAndField)
{
    const std::string ok = "0,1,2,3,0,0,-1,30\n";
    struct Case
    {
        std::string text, expect;
    };
    const Case cases[] = {
        {ok + "0.1,1,2,3,0,0,-1\n", "cut.path:2: expected 8 fields"},        // truncated line
        {ok + "0.1,1,2,3,0,0,-1\n", "field length missing"},
        {ok + "0.1,1,2\n", "field z missing"},
        {ok + "0.1,1,2,3,0,0,-1,30,7\n", "cut.path:2: expected 8 fields"},    // too many
        {ok + "0.1,nan,2,3,0,0,-1,30\n", "cut.path:2: field x: 'nan' is not a finite number"},
        {ok + "0.1,1,2,inf,0,0,-1,30\n", "field z: 'inf' is not a finite number"},
        {ok + "0.1,1,2,1e999,0,0,-1,30\n", "field z"},
        {ok + "0.1,2.1e52,2,3,0,0,-1,30\n", "cut.path:2: field x: 2.1e+52 mm is out of range (at most 1e+06 mm"},
        {ok + "0.1,1,-1000001,3,0,0,-1,30\n", "field y: -1e+06 mm is out of range"},
        {ok + "0.1,1,2,3,0,0,-1,2e6\n", "field length: 2e+06 mm is out of range"},
        {ok + "0.1,1,2,3,0,0,-1,abc\n", "field length: 'abc' is not a number"},
        {ok + "0.1,1,2,3,0,0,-1,30mm\n", "field length: '30mm' is not a number"},
        {ok + "0.1,1,,3,0,0,-1,30\n", "field y: empty"},
        {ok + "0.1,1,2,3,0,0,-1,0\n", "cut.path:2: field length: blade length must be > 0"},
        {ok + "0.1,1,2,3,0,0,-1,-5\n", "field length"},
        {ok + "0.1,1,2,3,0,0,0,30\n", "cut.path:2: field dx,dy,dz: direction is zero"},
        {ok + "# c\n-0.5,1,2,3,0,0,-1,30\n", "cut.path:3: field t: time goes backwards"},
        {"t,x,y,z\n", "cut.path:1: field t: 't' is not a number"}, // a broken header is not a header
    };
    for (const Case& c : cases) {
        const std::string e = errorOf(c.text);
        EXPECT_NE(e.find(c.expect), std::string::npos) << "text:\n" << c.text << "error: " << e;
    }
    EXPECT_EQ(errorOf("# only comments\n\n"), "");
    EXPECT_TRUE(parse("# only comments\n\nstroke\n").empty());
    EXPECT_THROW(readPathFile("/nonexistent/cut.path"), mtcut::InputError);
}

TEST(PathFile, EndStopsReadingAndParseLineKinds)
{
    const auto s = parse("0,1,2,3,0,0,-1,30\nend\ngarbage that is never read\n");
    ASSERT_EQ(s.size(), 1u);
    EXPECT_EQ(parsePathLine("stroke", 1, "x").kind, PathLine::Kind::StrokeBreak);
    EXPECT_EQ(parsePathLine("  \r", 1, "x").kind, PathLine::Kind::StrokeBreak);
    EXPECT_EQ(parsePathLine("#", 1, "x").kind, PathLine::Kind::Skip);
    EXPECT_EQ(parsePathLine("t,x,y,z,dx,dy,dz,length", 1, "x").kind, PathLine::Kind::Skip);
    EXPECT_EQ(parsePathLine("end", 1, "x").kind, PathLine::Kind::End);
}

TEST(PathFile, WriteReadRoundTripIsExact)
{
    IndexFrame f;
    f.dims = glm::ivec3(100, 100, 50);
    f.spacing = glm::dvec3(0.4, 0.4, 1.25);
    f.origin = glm::dvec3(-20.3, 11.1, -700.7);
    const auto strokes = makeRandomStrokes(f, 9, 7, 300);
    std::ostringstream out;
    writePath(out, strokes);
    const auto back = parse(out.str());
    ASSERT_EQ(back.size(), strokes.size());
    for (size_t s = 0; s < strokes.size(); ++s) {
        ASSERT_EQ(back[s].size(), strokes[s].size());
        for (size_t i = 0; i < strokes[s].size(); ++i) {
            EXPECT_EQ(back[s][i].time, strokes[s][i].time);
            EXPECT_EQ(back[s][i].base, strokes[s][i].base);
            EXPECT_EQ(back[s][i].length, strokes[s][i].length);
            // Directions were unit already; normalising again moves them by <= 1 ulp-ish.
            EXPECT_NEAR(glm::distance(back[s][i].direction, strokes[s][i].direction), 0.0, 1e-15);
        }
    }
}

TEST(PathFile, RandomGarbageNeverCrashes)
{
    // Seeded mutations of a valid file: every outcome is a parse or an InputError.
    std::mt19937 rng(17);
    const std::string base = "t,x,y,z,dx,dy,dz,length\n0,1,2,3,0,0,-1,30\n0.1,1.5,2,3,0,0.1,-1,30\n";
    const std::string alphabet = "0123456789.,-+eE#\n nainfstroke\r";
    size_t parsed = 0, rejected = 0;
    for (int i = 0; i < 5000; ++i) {
        std::string t = base;
        const int edits = 1 + int(rng() % 4);
        for (int e = 0; e < edits; ++e) {
            const size_t pos = rng() % (t.size() + 1);
            switch (rng() % 3) {
            case 0: t.insert(pos, 1, alphabet[rng() % alphabet.size()]); break;
            case 1: if (pos < t.size()) t.erase(pos, 1); break;
            default: t = t.substr(0, pos); break; // truncation
            }
        }
        try {
            const auto s = parse(t);
            for (const auto& st : s)
                for (const Pose& p : st) {
                    ASSERT_GT(p.length, 0.0);
                    ASSERT_NEAR(glm::length(p.direction), 1.0, 1e-12);
                }
            ++parsed;
        } catch (const mtcut::InputError& e) {
            ASSERT_EQ(std::string(e.what()).rfind("cut.path:", 0), 0u) << e.what();
            ++rejected;
        }
    }
    EXPECT_GT(parsed, 100u);
    EXPECT_GT(rejected, 100u);
}
