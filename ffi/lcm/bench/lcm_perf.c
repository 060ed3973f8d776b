/*
 * lcm_perf: the LCM latency and throughput benchmark written directly on liblcm, the baseline
 * the Rust program ffi/lcm/examples/lcm_perf.rs is compared with. Both speak the same protocol
 * and print the same result line, so scripts/bench can run them side by side.
 *
 *   lcm_perf pong   URL                      echo PERF_PING back on PERF_PONG until killed
 *   lcm_perf ping   URL SIZE COUNT           COUNT round trips of SIZE-byte messages
 *   lcm_perf sink   URL                      receive PERF_DATA, acknowledge on PERF_ACK
 *   lcm_perf source URL SIZE COUNT WINDOW    send COUNT messages, at most WINDOW unacknowledged
 *   lcm_perf loop   URL SIZE COUNT           publish and handle COUNT messages in one process
 *                                            (memq://: the library's own cost per message)
 */
#include <lcm/lcm.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static int64_t now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static void put_u64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }
static uint64_t get_u64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }

/* ---- pong ---- */
static void on_ping(const lcm_recv_buf_t *rbuf, const char *channel, void *user) {
    (void)channel;
    lcm_publish((lcm_t *)user, "PERF_PONG", rbuf->data, rbuf->data_size);
}

/* ---- ping ---- */
struct ping_state { uint64_t want; int got; };
static void on_pong(const lcm_recv_buf_t *rbuf, const char *channel, void *user) {
    (void)channel;
    struct ping_state *s = user;
    if (rbuf->data_size >= 8 && get_u64(rbuf->data) == s->want) s->got = 1;
}

static int cmp_i64(const void *a, const void *b) {
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

static int64_t pct(const int64_t *v, int n, double p) {
    int rank = (int)((p / 100.0) * n + 0.999999);
    if (rank < 1) rank = 1;
    if (rank > n) rank = n;
    return v[rank - 1];
}

/* ---- sink ---- */
struct sink_state { lcm_t *lcm; uint64_t count; uint64_t bytes; uint64_t ack_every; };
static void on_data(const lcm_recv_buf_t *rbuf, const char *channel, void *user) {
    (void)channel;
    struct sink_state *s = user;
    s->count++;
    s->bytes += rbuf->data_size;
    uint64_t total = rbuf->data_size >= 16 ? get_u64((const uint8_t *)rbuf->data + 8) : 0;
    if (s->count % s->ack_every == 0 || s->count == total) {
        uint8_t ack[8];
        put_u64(ack, s->count);
        lcm_publish(s->lcm, "PERF_ACK", ack, 8);
    }
}
static void on_reset(const lcm_recv_buf_t *rbuf, const char *channel, void *user) {
    (void)channel;
    struct sink_state *s = user;
    s->count = 0;
    s->bytes = 0;
    s->ack_every = rbuf->data_size >= 8 ? get_u64(rbuf->data) : 1;
    if (s->ack_every == 0) s->ack_every = 1;
    uint8_t ack[8];
    put_u64(ack, 0);
    lcm_publish(s->lcm, "PERF_ACK", ack, 8);
}

/* ---- source ---- */
struct source_state { uint64_t acked; int seen; };
static void on_ack(const lcm_recv_buf_t *rbuf, const char *channel, void *user) {
    (void)channel;
    struct source_state *s = user;
    if (rbuf->data_size >= 8) { s->acked = get_u64(rbuf->data); s->seen = 1; }
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: lcm_perf pong|ping|sink|source URL [SIZE COUNT [WINDOW]]\n");
        return 2;
    }
    const char *mode = argv[1];
    lcm_t *lcm = lcm_create(argv[2]);
    if (!lcm) { fprintf(stderr, "lcm_create(%s) failed\n", argv[2]); return 1; }

    if (!strcmp(mode, "pong")) {
        lcm_subscription_t *s = lcm_subscribe(lcm, "PERF_PING", on_ping, lcm);
        lcm_subscription_set_queue_capacity(s, 10000);
        for (;;) lcm_handle(lcm);
    } else if (!strcmp(mode, "sink")) {
        struct sink_state st = { lcm, 0, 0, 1 };
        lcm_subscription_t *s = lcm_subscribe(lcm, "PERF_DATA", on_data, &st);
        lcm_subscription_set_queue_capacity(s, 0);
        lcm_subscribe(lcm, "PERF_RESET", on_reset, &st);
        for (;;) lcm_handle(lcm);
    } else if (!strcmp(mode, "ping") && argc >= 5) {
        int size = atoi(argv[3]), count = atoi(argv[4]);
        if (size < 8) size = 8;
        uint8_t *buf = calloc(1, size);
        int64_t *rtt = calloc(count, sizeof(int64_t));
        struct ping_state st = { 0, 0 };
        lcm_subscribe(lcm, "PERF_PONG", on_pong, &st);
        /* Warm up until the pong answers (it may still be starting). */
        int warm = 0;
        for (int tries = 0; tries < 200 && warm < 50; tries++) {
            st.want = 1ULL << 62 | (uint64_t)tries; st.got = 0;
            put_u64(buf, st.want);
            lcm_publish(lcm, "PERF_PING", buf, size);
            while (!st.got && lcm_handle_timeout(lcm, 100) > 0) {}
            if (st.got) warm++;
        }
        int n = 0, lost = 0;
        for (int i = 0; i < count; i++) {
            st.want = (uint64_t)i; st.got = 0;
            put_u64(buf, st.want);
            int64_t t0 = now_ns();
            lcm_publish(lcm, "PERF_PING", buf, size);
            while (!st.got) {
                if (lcm_handle_timeout(lcm, 1000) <= 0) break;
            }
            if (st.got) rtt[n++] = now_ns() - t0; else lost++;
        }
        qsort(rtt, n, sizeof(int64_t), cmp_i64);
        double sum = 0;
        for (int i = 0; i < n; i++) sum += rtt[i];
        printf("impl=c mode=latency size=%d count=%d lost=%d p50_us=%.2f p90_us=%.2f p99_us=%.2f mean_us=%.2f rtt_ns=",
               size, count, lost, pct(rtt, n, 50) / 1e3, pct(rtt, n, 90) / 1e3, pct(rtt, n, 99) / 1e3,
               n ? sum / n / 1e3 : 0.0);
        /* Every round trip, sorted, so that percentiles can be pooled over runs. */
        for (int i = 0; i < n; i++) printf(i ? ",%lld" : "%lld", (long long)rtt[i]);
        printf("\n");
    } else if (!strcmp(mode, "source") && argc >= 6) {
        int size = atoi(argv[3]);
        uint64_t count = strtoull(argv[4], 0, 10), window = strtoull(argv[5], 0, 10);
        if (size < 16) size = 16;
        if (window < 1) window = 1;
        uint64_t ack_every = window / 2 ? window / 2 : 1;
        uint8_t *buf = calloc(1, size);
        struct source_state st = { 0, 0 };
        lcm_subscribe(lcm, "PERF_ACK", on_ack, &st);
        uint8_t reset[8];
        put_u64(reset, ack_every);
        for (int tries = 0; tries < 100 && !st.seen; tries++) {
            lcm_publish(lcm, "PERF_RESET", reset, 8);
            lcm_handle_timeout(lcm, 100);
        }
        if (!st.seen) { fprintf(stderr, "no sink answered\n"); return 1; }
        st.acked = 0;
        int64_t t0 = now_ns();
        uint64_t sent = 0;
        int stalled = 0;
        while (st.acked < count && !stalled) {
            while (sent < count && sent - st.acked < window) {
                put_u64(buf, sent);
                put_u64(buf + 8, count);
                lcm_publish(lcm, "PERF_DATA", buf, size);
                sent++;
            }
            if (lcm_handle_timeout(lcm, 1000) <= 0) stalled = 1;
        }
        double secs = (now_ns() - t0) / 1e9;
        printf("impl=c mode=throughput size=%d count=%llu lost=%llu msgs_per_s=%.1f mb_per_s=%.2f\n",
               size, (unsigned long long)count, (unsigned long long)(count - st.acked),
               st.acked / secs, st.acked * (double)size / secs / 1e6);
    } else if (!strcmp(mode, "loop") && argc >= 5) {
        int size = atoi(argv[3]), count = atoi(argv[4]);
        uint8_t *buf = calloc(1, size > 8 ? size : 8);
        struct sink_state st = { lcm, 0, 0, (uint64_t)-1 };
        lcm_subscribe(lcm, "PERF_DATA", on_data, &st);
        for (int i = 0; i < count; i++) {
            lcm_publish(lcm, "PERF_DATA", buf, size);
            lcm_handle(lcm);
        }
        printf("impl=c mode=loop size=%d count=%d received=%llu\n", size, count, (unsigned long long)st.count);
    } else {
        fprintf(stderr, "bad arguments\n");
        return 2;
    }
    lcm_destroy(lcm);
    return 0;
}
