/* A fake Arduino Due joint-controller board: see fake_due.h. */
#include "fake_due.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stride_link.h"

#define MAX_JOINTS 8
#define OUT_CAP 4096

typedef struct {
    int mode;          /* STRIDE_LINK_MODE_* */
    double duty;       /* applied, -1..1 */
    double target;     /* position mode, rad */
    double position;   /* rad */
    double velocity;   /* rad/s */
    double current_ma;
    double extra_ma;
    uint8_t faults;
    int braked;
} joint;

struct fake_due {
    fake_due_config cfg;
    stride_link_decoder dec;
    joint j[MAX_JOINTS];
    uint8_t seq;           /* next sequence number to send */
    uint8_t ack;           /* seq of the last COMMAND applied */
    int session;           /* a HELLO was answered */
    int watchdog_tripped;
    uint64_t t0, last_t, last_alive, next_state, next_imu;
    double roll, pitch;
    uint32_t noise;
    uint8_t out[OUT_CAP];
    size_t out_n;
};

static void send(fake_due *d, stride_link_frame *f) {
    uint8_t buf[STRIDE_LINK_MAX_ENCODED];
    size_t n;
    f->seq = d->seq++;
    n = stride_link_encode(f, buf, sizeof buf);
    if (n && d->out_n + n <= OUT_CAP) {
        memcpy(d->out + d->out_n, buf, n);
        d->out_n += n;
    }
}

static void begin(stride_link_frame *f, uint8_t type) {
    f->type = type;
    f->len = 0;
}

static void nack(fake_due *d, uint8_t seq, uint8_t reason) {
    stride_link_frame f;
    begin(&f, STRIDE_LINK_NACK);
    stride_link_put_u8(&f, seq);
    stride_link_put_u8(&f, reason);
    send(d, &f);
}

static void fault(fake_due *d, uint8_t joint_index, uint8_t bits, uint16_t detail) {
    stride_link_frame f;
    begin(&f, STRIDE_LINK_FAULT);
    stride_link_put_u8(&f, joint_index);
    stride_link_put_u8(&f, bits);
    stride_link_put_u16(&f, detail);
    send(d, &f);
}

static void brake_all(fake_due *d) {
    for (int i = 0; i < d->cfg.joints; i++) {
        d->j[i].mode = STRIDE_LINK_MODE_BRAKE;
        d->j[i].duty = 0;
        d->j[i].braked = 1;
    }
}

fake_due *fake_due_new(const fake_due_config *cfg, uint64_t t_us) {
    fake_due *d = calloc(1, sizeof *d);
    if (!d) {
        return NULL;
    }
    d->cfg = *cfg;
    if (d->cfg.joints > MAX_JOINTS) {
        d->cfg.joints = MAX_JOINTS;
    }
    stride_link_decoder_init(&d->dec);
    d->t0 = d->last_t = d->last_alive = d->next_state = d->next_imu = t_us;
    d->noise = 12345;
    brake_all(d);
    return d;
}

void fake_due_free(fake_due *d) { free(d); }

static void on_frame(fake_due *d, const stride_link_frame *f, uint64_t t_us) {
    size_t at = 0;
    stride_link_frame r;
    switch (f->type) {
    case STRIDE_LINK_HELLO: {
        uint8_t major, minor;
        uint32_t nonce;
        if (stride_link_get_u8(f, &at, &major) || stride_link_get_u8(f, &at, &minor) ||
            stride_link_get_u32(f, &at, &nonce) || at != f->len) {
            nack(d, f->seq, STRIDE_LINK_NACK_PAYLOAD);
            return;
        }
        if (major != STRIDE_LINK_MAJOR) {
            nack(d, f->seq, STRIDE_LINK_NACK_VERSION);
            return;
        }
        /* A new session: motors braked, counting afresh. */
        brake_all(d);
        d->seq = 0;
        d->session = 1;
        d->watchdog_tripped = 0;
        d->last_alive = t_us;
        begin(&r, STRIDE_LINK_HELLO_ACK);
        stride_link_put_u8(&r, STRIDE_LINK_MAJOR);
        stride_link_put_u8(&r, STRIDE_LINK_MINOR);
        stride_link_put_u32(&r, nonce);
        stride_link_put_u8(&r, d->cfg.joints);
        stride_link_put_u16(&r, d->cfg.watchdog_ms);
        stride_link_put_u16(&r, d->cfg.max_duty);
        stride_link_put_u16(&r, d->cfg.current_limit_ma);
        {
            const char name[16] = "fake-due 1.0";
            for (int i = 0; i < 16; i++) {
                stride_link_put_u8(&r, (uint8_t)name[i]);
            }
        }
        send(d, &r);
        return;
    }
    case STRIDE_LINK_HEARTBEAT: {
        uint32_t t;
        if (stride_link_get_u32(f, &at, &t) || at != f->len) {
            nack(d, f->seq, STRIDE_LINK_NACK_PAYLOAD);
            return;
        }
        if (!d->session) {
            nack(d, f->seq, STRIDE_LINK_NACK_NO_HANDSHAKE);
            return;
        }
        d->last_alive = t_us;
        begin(&r, STRIDE_LINK_HEARTBEAT_ACK);
        stride_link_put_u32(&r, (uint32_t)((t_us - d->t0) / 1000));
        send(d, &r);
        return;
    }
    case STRIDE_LINK_COMMAND: {
        uint8_t count, ji[MAX_JOINTS], mode[MAX_JOINTS];
        uint16_t raw[MAX_JOINTS];
        if (!d->session) {
            nack(d, f->seq, STRIDE_LINK_NACK_NO_HANDSHAKE);
            return;
        }
        if (stride_link_get_u8(f, &at, &count) || count > MAX_JOINTS) {
            nack(d, f->seq, STRIDE_LINK_NACK_PAYLOAD);
            return;
        }
        for (int k = 0; k < count; k++) {
            if (stride_link_get_u8(f, &at, &ji[k]) || stride_link_get_u8(f, &at, &mode[k]) ||
                stride_link_get_u16(f, &at, &raw[k])) {
                nack(d, f->seq, STRIDE_LINK_NACK_PAYLOAD);
                return;
            }
            if (ji[k] >= d->cfg.joints || mode[k] > STRIDE_LINK_MODE_POSITION ||
                (mode[k] == STRIDE_LINK_MODE_DUTY && abs((int16_t)raw[k]) > d->cfg.max_duty)) {
                nack(d, f->seq, STRIDE_LINK_NACK_RANGE);
                return;
            }
        }
        if (at != f->len) {
            nack(d, f->seq, STRIDE_LINK_NACK_PAYLOAD);
            return;
        }
        /* All checked: apply. */
        d->last_alive = t_us;
        d->watchdog_tripped = 0;
        d->ack = f->seq;
        for (int k = 0; k < count; k++) {
            joint *j = &d->j[ji[k]];
            int16_t v = (int16_t)raw[k];
            if (j->faults & STRIDE_LINK_FAULT_OVER_CURRENT) {
                /* Stays braked until told to coast or brake. */
                if (mode[k] == STRIDE_LINK_MODE_COAST || mode[k] == STRIDE_LINK_MODE_BRAKE) {
                    j->faults &= (uint8_t)~STRIDE_LINK_FAULT_OVER_CURRENT;
                } else {
                    continue;
                }
            }
            j->faults &= (uint8_t)~STRIDE_LINK_FAULT_WATCHDOG;
            j->mode = mode[k];
            j->braked = mode[k] == STRIDE_LINK_MODE_BRAKE;
            if (mode[k] == STRIDE_LINK_MODE_DUTY) {
                j->duty = v / 10000.0;
            } else if (mode[k] == STRIDE_LINK_MODE_POSITION) {
                j->target = v / 10000.0;
            } else {
                j->duty = 0;
            }
        }
        return;
    }
    default:
        nack(d, f->seq, STRIDE_LINK_NACK_TYPE);
    }
}

void fake_due_receive(fake_due *d, const uint8_t *bytes, size_t n, uint64_t t_us) {
    stride_link_frame f;
    for (size_t i = 0; i < n; i++) {
        if (stride_link_decoder_push(&d->dec, bytes[i], &f) == 1) {
            on_frame(d, &f, t_us);
        }
    }
}

/* A small deterministic noise in [-1, 1]. */
static double noise(fake_due *d) {
    d->noise = d->noise * 1103515245u + 12345u;
    return ((d->noise >> 16) & 0x7fff) / 16383.5 - 1.0;
}

static void simulate(fake_due *d, double dt) {
    for (int i = 0; i < d->cfg.joints; i++) {
        joint *j = &d->j[i];
        double tau, v_target;
        if (j->mode == STRIDE_LINK_MODE_POSITION && !j->braked &&
            !(j->faults & STRIDE_LINK_FAULT_OVER_CURRENT)) {
            double e = j->target - j->position;
            double max = d->cfg.max_duty / 10000.0;
            j->duty = 4.0 * e - 0.2 * j->velocity;
            if (j->duty > max) j->duty = max;
            if (j->duty < -max) j->duty = -max;
        }
        if (j->braked) {
            v_target = 0;
            tau = 0.005;
        } else if (j->mode == STRIDE_LINK_MODE_COAST) {
            v_target = 0;
            tau = 0.5;
        } else {
            v_target = 5.0 * j->duty; /* 5 rad/s at full duty */
            tau = 0.05;
        }
        j->velocity += (v_target - j->velocity) * (1.0 - exp(-dt / tau));
        j->position += j->velocity * dt;
        j->current_ma = (j->braked ? 0 : 300.0 + 6000.0 * fabs(j->duty)) + j->extra_ma;
        if (j->current_ma > d->cfg.current_limit_ma && !(j->faults & STRIDE_LINK_FAULT_OVER_CURRENT)) {
            j->faults |= STRIDE_LINK_FAULT_OVER_CURRENT;
            j->braked = 1;
            j->duty = 0;
            j->mode = STRIDE_LINK_MODE_BRAKE;
            fault(d, (uint8_t)i, STRIDE_LINK_FAULT_OVER_CURRENT, (uint16_t)j->current_ma);
        }
    }
}

static void put_i16(stride_link_frame *f, double v) {
    long r = lround(v);
    if (r > 32767) r = 32767;
    if (r < -32768) r = -32768;
    stride_link_put_u16(f, (uint16_t)(int16_t)r);
}

size_t fake_due_poll(fake_due *d, uint64_t t_us, uint8_t *out, size_t cap) {
    size_t n;
    if (t_us > d->last_t) {
        /* Simulate in steps of at most 1 ms. */
        while (d->last_t < t_us) {
            uint64_t step = t_us - d->last_t > 1000 ? 1000 : t_us - d->last_t;
            simulate(d, step / 1e6);
            d->last_t += step;
        }
    }
    if (d->session && !d->watchdog_tripped &&
        t_us - d->last_alive > (uint64_t)d->cfg.watchdog_ms * 1000) {
        d->watchdog_tripped = 1;
        brake_all(d);
        for (int i = 0; i < d->cfg.joints; i++) {
            d->j[i].faults |= STRIDE_LINK_FAULT_WATCHDOG;
        }
        fault(d, 0xFF, STRIDE_LINK_FAULT_WATCHDOG, d->cfg.watchdog_ms);
    }
    if (d->session && t_us >= d->next_state) {
        stride_link_frame f;
        d->next_state += (uint64_t)d->cfg.state_period_ms * 1000;
        if (d->next_state < t_us) d->next_state = t_us + (uint64_t)d->cfg.state_period_ms * 1000;
        begin(&f, STRIDE_LINK_STATE);
        stride_link_put_u32(&f, (uint32_t)((t_us - d->t0) / 1000));
        stride_link_put_u8(&f, d->ack);
        stride_link_put_u8(&f, d->cfg.joints);
        for (int i = 0; i < d->cfg.joints; i++) {
            joint *j = &d->j[i];
            stride_link_put_u32(&f, (uint32_t)(int32_t)lround(j->position * 1e5));
            put_i16(&f, j->velocity * 1e3);
            put_i16(&f, j->current_ma);
            stride_link_put_u8(&f, (uint8_t)(int8_t)30);
            put_i16(&f, j->duty * 1e4);
            stride_link_put_u8(&f, (uint8_t)((j->braked ? 1 : 0) | j->faults << 1));
        }
        send(d, &f);
    }
    if (d->session && t_us >= d->next_imu) {
        stride_link_frame f;
        const double g = 16384.0, gyro = 131.0; /* counts per g, per deg/s (±2 g, ±250 deg/s) */
        d->next_imu += (uint64_t)d->cfg.imu_period_ms * 1000;
        if (d->next_imu < t_us) d->next_imu = t_us + (uint64_t)d->cfg.imu_period_ms * 1000;
        begin(&f, STRIDE_LINK_IMU);
        stride_link_put_u32(&f, (uint32_t)(t_us - d->t0));
        put_i16(&f, -sin(d->pitch) * g + 40 * noise(d));
        put_i16(&f, sin(d->roll) * cos(d->pitch) * g + 40 * noise(d));
        put_i16(&f, cos(d->roll) * cos(d->pitch) * g + 40 * noise(d));
        put_i16(&f, (30.0 - 36.53) * 340.0);
        put_i16(&f, 0.3 * gyro + 5 * noise(d)); /* a small gyro bias */
        put_i16(&f, -0.2 * gyro + 5 * noise(d));
        put_i16(&f, 5 * noise(d));
        send(d, &f);
    }
    n = d->out_n < cap ? d->out_n : cap;
    memcpy(out, d->out, n);
    memmove(d->out, d->out + n, d->out_n - n);
    d->out_n -= n;
    return n;
}

void fake_due_set_extra_current(fake_due *d, int joint_index, double ma) {
    if (joint_index >= 0 && joint_index < d->cfg.joints) {
        d->j[joint_index].extra_ma = ma;
    }
}

void fake_due_set_tilt(fake_due *d, double roll, double pitch) {
    d->roll = roll;
    d->pitch = pitch;
}

int fake_due_duty(const fake_due *d, int joint_index) {
    return (int)lround(d->j[joint_index].duty * 10000);
}

int fake_due_braked(const fake_due *d, int joint_index) { return d->j[joint_index].braked; }

double fake_due_position(const fake_due *d, int joint_index) { return d->j[joint_index].position; }
