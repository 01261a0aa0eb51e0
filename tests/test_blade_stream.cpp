// Pose streams: the lock-free queue, stdin-like streams and UDP on loopback.
#include "cutter/PathFile.h"
#include "cutter/PoseStream.h"
#include "vdb/Error.h"

#include <gtest/gtest.h>

#include <chrono>
#include <sstream>
#include <thread>

using namespace mtcut::cutter;

TEST(SpscQueue, OrderAndNoLossAcrossThreads)
{
    SpscQueue<uint64_t, 64> q; // small blocks: many block switches
    constexpr uint64_t kCount = 2'000'000;
    std::thread producer([&] {
        for (uint64_t i = 0; i < kCount; ++i) q.push(i);
        q.close();
    });
    uint64_t expected = 0;
    while (true) {
        const bool closed = q.closed();
        uint64_t v;
        while (q.tryPop(v)) {
            ASSERT_EQ(v, expected);
            ++expected;
        }
        if (closed) break;
    }
    producer.join();
    EXPECT_EQ(expected, kCount);
    EXPECT_EQ(q.pushedCount(), kCount);
}

TEST(PoseStream, StreamSourceFeedsTheInputThread)
{
    IndexFrame f;
    f.dims = glm::ivec3(64, 64, 64);
    std::istringstream in("t,x,y,z,dx,dy,dz,length\n"
                          "0,10.5,10.5,40.5,0,0,-1,20\n"
                          "0.001,12.5,10.5,40.5,0,0,-1,20\n"
                          "0.002,14.5,10.5,40.5,0,0,-1,20\n"
                          "0.001,16.5,10.5,40.5,0,0,-1,20\n" // time goes backwards: error item
                          "stroke\n"
                          "0,30.5,30.5,40.5,1,0,0,5\n"
                          "0.1,30.5,32.5,40.5,1,0,0,5\n");
    InputThread input(std::make_unique<StreamLineSource>(in, "stdin"), f);
    input.start();
    input.join();
    std::vector<CutInfo> items;
    CutInfo info;
    while (input.queue().tryPop(info)) items.push_back(info);
    ASSERT_TRUE(input.queue().closed());
    ASSERT_EQ(items.size(), 6u); // quad, quad, error, end, quad, end
    EXPECT_EQ(items[0].kind, CutInfo::Kind::Quad);
    EXPECT_EQ(items[1].quadIndex, 1u);
    EXPECT_EQ(items[2].kind, CutInfo::Kind::Error);
    EXPECT_NE(items[2].message.find("stdin:5:"), std::string::npos) << items[2].message;
    EXPECT_NE(items[2].message.find("time goes backwards"), std::string::npos);
    EXPECT_EQ(items[3].kind, CutInfo::Kind::StrokeEnd);
    EXPECT_EQ(items[4].stroke, 1u);
    EXPECT_EQ(items[4].quadIndex, 0u);
    EXPECT_EQ(items[4].line, 8u);
    EXPECT_FALSE(items[4].cells.empty());
    EXPECT_EQ(input.posesRead(), 6u);
    EXPECT_EQ(input.errors(), 1u);
}

TEST(PoseStream, UdpLoopbackDeliversLinesInOrder)
{
    IndexFrame f;
    f.dims = glm::ivec3(64, 64, 64);
    auto source = std::make_unique<UdpLineSource>(0);
    const uint16_t port = source->port();
    ASSERT_NE(port, 0);
    EXPECT_EQ(source->name(), "udp:127.0.0.1:" + std::to_string(port));
    InputThread input(std::move(source), f);
    input.start();
    // 200 poses, a few per datagram, then `end`. Bounded in count and time.
    constexpr int kPoses = 200;
    std::string datagram;
    for (int i = 0; i < kPoses; ++i) {
        Pose p;
        p.time = i * 0.001;
        p.base = glm::dvec3(5.5 + 0.25 * i, 20.5, 40.5);
        p.direction = glm::dvec3(0, 0.2, -1);
        p.length = 10;
        datagram += formatPoseLine(p) + "\n";
        if (i % 4 == 3) {
            sendUdpLoopback(port, datagram);
            datagram.clear();
            std::this_thread::sleep_for(std::chrono::microseconds(200));
        }
    }
    // The blade stops at x = 55.9, in the last kept stick's cell (55).
    datagram += "0.2,55.9,20.5,40.5,0,0.2,-1,10\n";
    sendUdpLoopback(port, datagram + "end\n");
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    std::vector<CutInfo> items;
    CutInfo info;
    while (std::chrono::steady_clock::now() < deadline) {
        const bool closed = input.queue().closed();
        while (input.queue().tryPop(info)) items.push_back(info);
        if (closed) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    input.stop();
    input.join();
    ASSERT_TRUE(input.queue().closed()) << "timed out";
    EXPECT_EQ(input.posesRead(), uint64_t(kPoses + 1));
    EXPECT_EQ(input.errors(), 0u);
    // One stick per cell: the base moves 0.25 mm per pose = a quarter cell.
    size_t quads = 0;
    for (size_t i = 0; i < items.size(); ++i)
        if (items[i].kind == CutInfo::Kind::Quad) {
            EXPECT_EQ(items[i].quadIndex, quads);
            ++quads;
        }
    // x from 5.5 to 55.9 crosses the 50 cell borders 6..55: one quad each,
    // and one more to the last pose (55.9, in the last stick's cell) when the
    // stream ends (PathFilter::finishStroke).
    EXPECT_EQ(quads, 51u);
    ASSERT_GE(items.size(), 2u);
    EXPECT_EQ(items.back().kind, CutInfo::Kind::StrokeEnd);
    EXPECT_EQ(items[items.size() - 2].quad.corners[3].x, 55.9) << "the last quad ends at the last pose";
}

TEST(PoseStream, UdpStopEndsAnIdleSource)
{
    UdpLineSource source(0);
    std::thread t([&] {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        source.stop();
    });
    std::string line;
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_FALSE(source.next(line));
    EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(2));
    t.join();
}
