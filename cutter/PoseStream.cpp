#include "cutter/PoseStream.h"

#include "cutter/PathFile.h"
#include "vdb/Error.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <istream>
#include <string_view>

namespace mtcut::cutter {

bool StreamLineSource::next(std::string& line)
{
    return bool(std::getline(mIn, line));
}

bool MemoryLineSource::next(std::string& line)
{
    if (mNext >= mLines.size()) return false;
    line = std::move(mLines[mNext++]);
    return true;
}

// ---------------------------------------------------------------------------

UdpLineSource::UdpLineSource(uint16_t port)
{
    mSocket = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (mSocket < 0) throw InputError(std::string("udp: cannot create socket: ") + std::strerror(errno));
    int size = 4 << 20;
    ::setsockopt(mSocket, SOL_SOCKET, SO_RCVBUF, &size, sizeof(size)); // best effort
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::bind(mSocket, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
        const std::string err = std::strerror(errno);
        ::close(mSocket);
        throw InputError("udp:127.0.0.1:" + std::to_string(port) + ": cannot bind: " + err);
    }
    socklen_t len = sizeof(addr);
    ::getsockname(mSocket, reinterpret_cast<sockaddr*>(&addr), &len);
    mPort = ntohs(addr.sin_port);
}

UdpLineSource::~UdpLineSource()
{
    if (mSocket >= 0) ::close(mSocket);
}

std::string UdpLineSource::name() const
{
    return "udp:127.0.0.1:" + std::to_string(mPort);
}

bool UdpLineSource::next(std::string& line)
{
    while (true) {
        if (mEnded) return false;
        if (mPendingNext < mPending.size()) {
            line = std::move(mPending[mPendingNext++]);
            return true;
        }
        mPending.clear();
        mPendingNext = 0;
        if (mStop.load()) return false;
        pollfd p{mSocket, POLLIN, 0};
        const int r = ::poll(&p, 1, 100);
        if (r < 0 && errno != EINTR) return false;
        if (r <= 0) continue;
        mBuffer.resize(65536);
        const ssize_t n = ::recv(mSocket, mBuffer.data(), mBuffer.size(), 0);
        if (n <= 0) continue;
        // One line per '\n'; text after the last '\n' is a line too.
        const std::string_view d(mBuffer.data(), size_t(n));
        size_t start = 0;
        while (start < d.size()) {
            const size_t nl = d.find('\n', start);
            if (nl == std::string_view::npos) {
                mPending.emplace_back(d.substr(start));
                break;
            }
            mPending.emplace_back(d.substr(start, nl - start));
            start = nl + 1;
        }
        for (size_t i = 0; i < mPending.size(); ++i)
            if (mPending[i] == "end" || mPending[i] == "end\r") {
                mPending.resize(i + 1); // deliver `end` itself, then stop
                break;
            }
    }
}

void sendUdpLoopback(uint16_t port, const std::string& text)
{
    const int s = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (s < 0) throw InputError(std::string("udp: cannot create socket: ") + std::strerror(errno));
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    const ssize_t n = ::sendto(s, text.data(), text.size(), 0, reinterpret_cast<sockaddr*>(&addr),
                               sizeof(addr));
    const int err = errno;
    ::close(s);
    if (n != ssize_t(text.size()))
        throw InputError("udp:127.0.0.1:" + std::to_string(port) + ": send failed: " +
                         std::strerror(err));
}

// ---------------------------------------------------------------------------

InputThread::InputThread(std::unique_ptr<LineSource> source, const IndexFrame& frame,
                         const InputThreadOptions& options)
    : mSource(std::move(source)), mFrame(frame), mOptions(options)
{
}

InputThread::~InputThread()
{
    stop();
    join();
}

void InputThread::start()
{
    assert(!mThread.joinable());
    mThread = std::thread([this] { run(); });
}

void InputThread::stop()
{
    if (mSource) mSource->stop();
}

void InputThread::join()
{
    if (mThread.joinable()) mThread.join();
}

void InputThread::run()
{
    PathFilter filter(mFrame, mOptions.filter);
    std::vector<Quad> quads;
    std::string line;
    uint64_t lineNumber = 0;
    uint32_t stroke = 0;
    uint32_t quadIndex = 0;
    const std::string source = mSource->name();
    double lastTime = 0.0;       // of the last pose pushed
    uint64_t lastPoseLine = 0;   // its line
    auto emit = [&](const std::vector<Quad>& made, uint64_t atLine, double time) {
        for (const Quad& q : made) {
            CutInfo info;
            info.kind = CutInfo::Kind::Quad;
            info.stroke = stroke;
            info.quadIndex = quadIndex++;
            info.line = atLine;
            info.time = time;
            info.quad = q;
            if (mOptions.voxelize) voxelizeCut(q, mOptions.kerfMm, mFrame, info.cells);
            mQueue.push(std::move(info));
            mQuads.fetch_add(1, std::memory_order_relaxed);
        }
    };
    auto endStroke = [&] {
        if (filter.posesSeen() == 0) return;
        const std::vector<Quad> last = filter.endStroke(); // the cut reaches the last pose
        if (!last.empty()) mSticks.fetch_add(1, std::memory_order_relaxed);
        emit(last, lastPoseLine, lastTime);
        CutInfo info;
        info.kind = CutInfo::Kind::StrokeEnd;
        info.stroke = stroke;
        info.line = lineNumber;
        mQueue.push(std::move(info));
        ++stroke;
        quadIndex = 0;
    };
    while (mSource->next(line)) {
        ++lineNumber;
        try {
            PathLine pl = parsePathLine(line, size_t(lineNumber), source);
            if (pl.kind == PathLine::Kind::End) break;
            if (pl.kind == PathLine::Kind::Skip) continue;
            if (pl.kind == PathLine::Kind::StrokeBreak) {
                endStroke();
                continue;
            }
            mPoses.fetch_add(1, std::memory_order_relaxed);
            quads.clear();
            // Sticks the pose added: itself, a held slide placed before it
            // (rule 2c) or a restart's (2b), none when dropped.
            const size_t sticksBefore = filter.sticks().size();
            try {
                filter.push(pl.pose, quads);
            } catch (const InputError& e) {
                throw InputError(source + ":" + std::to_string(lineNumber) + ": " + e.what());
            }
            mSticks.fetch_add(filter.sticks().size() - sticksBefore, std::memory_order_relaxed);
            lastTime = pl.pose.time;
            lastPoseLine = lineNumber;
            emit(quads, lineNumber, pl.pose.time);
        } catch (const InputError& e) {
            CutInfo info;
            info.kind = CutInfo::Kind::Error;
            info.stroke = stroke;
            info.line = lineNumber;
            info.message = e.what();
            mQueue.push(std::move(info));
            mErrors.fetch_add(1, std::memory_order_relaxed);
        }
    }
    endStroke();
    mQueue.close();
}

} // namespace mtcut::cutter
