// The simulations already made in this process, read back where one is asked for again (engine.hpp,
// simulate). A simulation is a pure function of the experiment's data, the setup (model and
// measurement) and the speed-ups of its Prepared, so a simulation read back is the same bits as one
// made again. Fits ask for the same simulation again where they walk a path another fit walked: the
// full run from the start a quick fit took, a model refitted from where it stands.
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <list>
#include <mutex>
#include <type_traits>
#include <unordered_map>
#include <vector>

#include "identify/engine.hpp"

namespace kt {

namespace {

static_assert(std::is_trivially_copyable<Setup>::value, "a setup is compared by its bytes");

struct Key {
    ContentHash content;              // Prepared::content: the experiment's data and outputs
    int stride = 1, continuous_input = 0;
    std::vector<unsigned char> setup; // the setup's bytes

    bool operator==(const Key &o) const
    {
        return content.a == o.content.a && content.b == o.content.b && stride == o.stride &&
               continuous_input == o.continuous_input && setup == o.setup;
    }
    std::uint64_t hash() const
    {
        ContentHash h = content;
        h.add_value(stride);
        h.add_value(continuous_input);
        h.add(setup.data(), setup.size());
        return h.a ^ (h.b << 1);
    }
};

struct Entry {
    std::uint64_t hash;
    Key key;
    std::vector<double> out;
    long long work; // the equation evaluations the simulation made
};

std::size_t entry_bytes(const Key &k, std::size_t n_out) { return sizeof(Entry) + k.setup.size() + 8 * n_out; }

class Cache {
  public:
    bool get(const Key &k, std::uint64_t h, double *out, std::size_t n, long long &work)
    {
        std::lock_guard<std::mutex> lock(m_);
        auto it = index_.find(h);
        if (it == index_.end() || !(it->second->key == k) || it->second->out.size() != n) return false;
        order_.splice(order_.begin(), order_, it->second); // the most recently used first
        std::copy(it->second->out.begin(), it->second->out.end(), out);
        work = it->second->work;
        return true;
    }
    void put(Key k, std::uint64_t h, const double *out, std::size_t n, long long work)
    {
        const std::size_t bytes = entry_bytes(k, n);
        std::lock_guard<std::mutex> lock(m_);
        if (bytes > capacity_) return;
        auto it = index_.find(h);
        if (it != index_.end()) drop(it->second);
        order_.push_front(Entry{h, std::move(k), std::vector<double>(out, out + n), work});
        index_[h] = order_.begin();
        bytes_ += bytes;
        while (bytes_ > capacity_) drop(std::prev(order_.end()));
    }
    long long set_capacity(long long bytes)
    {
        std::lock_guard<std::mutex> lock(m_);
        const long long before = (long long)capacity_;
        capacity_ = bytes > 0 ? (std::size_t)bytes : 0;
        while (bytes_ > capacity_) drop(std::prev(order_.end()));
        return before;
    }
  private:
    void drop(std::list<Entry>::iterator e)
    {
        bytes_ -= entry_bytes(e->key, e->out.size());
        index_.erase(e->hash);
        order_.erase(e);
    }

    std::mutex m_;
    std::list<Entry> order_; // the most recently used first
    std::unordered_map<std::uint64_t, std::list<Entry>::iterator> index_;
    std::size_t capacity_ = SIMULATION_CACHE_DEFAULT_BYTES, bytes_ = 0;
};

std::atomic<long long> reused{0}, made{0}; // simulations read back, and made

Cache &cache()
{
    static Cache c;
    return c;
}

Key key_of(const Prepared &p, const Setup &S)
{
    Key k;
    k.content = p.content;
    k.stride = p.stride;
    k.continuous_input = p.continuous_input ? 1 : 0;
    const unsigned char *b = reinterpret_cast<const unsigned char *>(&S);
    k.setup.assign(b, b + sizeof S);
    return k;
}

} // namespace

void ContentHash::add(const void *data, std::size_t bytes)
{
    const unsigned char *c = static_cast<const unsigned char *>(data);
    for (std::size_t i = 0; i < bytes; i += 8) {
        std::uint64_t w = 0;
        std::memcpy(&w, c + i, bytes - i < 8 ? bytes - i : 8);
        a = (a ^ w) * 1099511628211ULL;
        b = (b ^ w) * 0xBF58476D1CE4E5B9ULL;
        b ^= b >> 31;
    }
}

bool simulate(const Prepared &p, const Setup &S, double *out, std::string &err)
{
    const std::size_t n = (std::size_t)p.e->n * p.outputs.size();
    Key k = key_of(p, S);
    const std::uint64_t h = k.hash();
    long long work = 0;
    // read back only where the simulation made again would not be stopped by the fit's work cap
    // or its crawl cap either: its in-flight work never exceeds its whole work
    if (cache().get(k, h, out, n, work) && !(p.crawl_cap > 0 && work > p.crawl_cap) &&
        !(p.limits && p.limits->expired(p.limits->work_cap > 0 ? work : 0))) {
        last_simulation_work = work;
        if (p.limits) p.limits->work += work;
        ++reused;
        return true;
    }
    ++made;
    if (!simulate_physics(p, S, out, err)) return false;
    cache().put(std::move(k), h, out, n, last_simulation_work);
    return true;
}

long long set_simulation_cache_bytes(long long bytes) { return cache().set_capacity(bytes); }

void simulation_cache_counts(long long &n_reused, long long &n_made)
{
    n_reused = reused.load();
    n_made = made.load();
}

} // namespace kt
