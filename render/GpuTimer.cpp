#include "render/GpuTimer.h"

#include <algorithm>
#include <cassert>

namespace mtcut::render {

double FrameTimes::topLevelGpuMs() const
{
    double sum = 0.0;
    for (const PassTime& p : passes)
        if (p.depth == 0) sum += p.gpuMs;
    return sum;
}

const PassTime* FrameTimes::find(const std::string& name) const
{
    for (const PassTime& p : passes)
        if (p.name == name) return &p;
    return nullptr;
}

GpuTimer::GpuTimer(int ringFrames, Mode mode) : mMode(mode), mSlots(size_t(std::max(ringFrames, 1)))
{
    GLint bits = 0;
    glGetQueryiv(GL_TIMESTAMP, GL_QUERY_COUNTER_BITS, &bits); // core since GL 3.3
    mBits = bits;
    mGpu = mode == Mode::Auto && bits > 0;
    mLatest.gpuTimed = mGpu;
}

void GpuTimer::beginFrame()
{
    assert(!mInFrame && "GpuTimer::beginFrame: the previous frame was not ended");
    poll(false);
    Slot& slot = mSlots[size_t(mFrame % mSlots.size())];
    mInFrame = true;
    mOpen.clear();
    if (slot.pending) { // the GPU has not passed that frame yet: do not wait
        mCurrent = nullptr;
        ++mDropped;
    } else {
        mCurrent = &slot;
        slot.times.frame = mFrame;
        slot.times.gpuTimed = mGpu;
        slot.times.passes.clear();
    }
    ++mFrame;
}

void GpuTimer::endFrame()
{
    assert(mInFrame && "GpuTimer::endFrame without beginFrame");
    assert(mOpen.empty() && "GpuTimer::endFrame: a pass is still open");
    while (!mOpen.empty()) end(mOpen.back().index); // release builds: close them
    mInFrame = false;
    if (!mCurrent) return;
    Slot& slot = *mCurrent;
    mCurrent = nullptr;
    if (mGpu && !slot.times.passes.empty()) {
        slot.pending = true;
    } else {
        deliver(FrameTimes(slot.times)); // CPU times are final now
    }
}

int GpuTimer::begin(const std::string& name)
{
    if (!mCurrent) return -1;
    Slot& slot = *mCurrent;
    const int index = int(slot.times.passes.size());
    PassTime p;
    p.name = name;
    p.depth = int(mOpen.size());
    p.parent = mOpen.empty() ? -1 : mOpen.back().index;
    slot.times.passes.push_back(std::move(p));
    if (mGpu) {
        while (slot.queries.size() < 2 * slot.times.passes.size()) slot.queries.emplace_back(GL_TIMESTAMP);
        glQueryCounter(slot.queries[2 * size_t(index)].id(), GL_TIMESTAMP);
    } else if (mMode == Mode::CpuFinish) {
        glFinish();
    }
    mOpen.push_back({index, Clock::now()});
    return index;
}

void GpuTimer::end(int handle)
{
    if (handle < 0 || !mCurrent) return;
    assert(!mOpen.empty() && mOpen.back().index == handle && "GpuTimer::end: passes must close innermost first");
    // Release builds: close the passes opened inside this one too.
    while (!mOpen.empty() && mOpen.back().index >= handle) {
        const OpenPass open = mOpen.back();
        mOpen.pop_back();
        Slot& slot = *mCurrent;
        if (mGpu) {
            glQueryCounter(slot.queries[2 * size_t(open.index) + 1].id(), GL_TIMESTAMP);
        } else if (mMode == Mode::CpuFinish) {
            glFinish();
        }
        PassTime& p = slot.times.passes[size_t(open.index)];
        p.cpuMs = std::chrono::duration<double, std::milli>(Clock::now() - open.cpuBegin).count();
        if (!mGpu) p.gpuMs = p.cpuMs;
    }
}

bool GpuTimer::readSlot(Slot& slot, bool wait)
{
    const size_t n = slot.times.passes.size();
    if (!wait) {
        // Queries complete in order: the frame's last one decides.
        GLint available = GL_FALSE;
        glGetQueryObjectiv(slot.queries[2 * n - 1].id(), GL_QUERY_RESULT_AVAILABLE, &available);
        if (!available) return false;
    }
    for (size_t i = 0; i < n; ++i) {
        GLuint64 t0 = 0, t1 = 0;
        glGetQueryObjectui64v(slot.queries[2 * i].id(), GL_QUERY_RESULT, &t0);
        glGetQueryObjectui64v(slot.queries[2 * i + 1].id(), GL_QUERY_RESULT, &t1);
        slot.times.passes[i].gpuMs = t1 > t0 ? double(t1 - t0) * 1e-6 : 0.0;
    }
    slot.pending = false;
    deliver(FrameTimes(slot.times));
    return true;
}

void GpuTimer::poll(bool wait)
{
    // Pending slots in frame order (the GPU finishes them in that order).
    std::vector<Slot*> pending;
    for (Slot& s : mSlots)
        if (s.pending) pending.push_back(&s);
    std::sort(pending.begin(), pending.end(), [](const Slot* a, const Slot* b) { return a->times.frame < b->times.frame; });
    for (Slot* s : pending)
        if (!readSlot(*s, wait)) break;
}

void GpuTimer::deliver(FrameTimes&& times)
{
    mLatest = times;
    mArrived.push_back(std::move(times));
    while (mArrived.size() > 256) mArrived.pop_front();
}

std::vector<FrameTimes> GpuTimer::takeResults()
{
    poll(false);
    std::vector<FrameTimes> out(std::make_move_iterator(mArrived.begin()), std::make_move_iterator(mArrived.end()));
    mArrived.clear();
    return out;
}

void GpuTimer::finish()
{
    poll(true);
}

} // namespace mtcut::render
