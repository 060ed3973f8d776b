/*
 * legacy_controller: a joint controller written the way labs' existing C code is, with liblcm
 * and the C types lcm-gen makes from stride's .lcm files. The tests run it against the Rust
 * executables to show that both share one bus.
 *
 *   legacy_controller [-u URL] [-n JOINTS] [-r HZ] [-d SECONDS]
 *
 * It subscribes to JOINT_COMMAND (stride.joint_command_t) and moves its simulated joints toward
 * the commanded positions (at most 2 rad/s), publishes JOINT_STATE (stride.joint_state_t) at
 * HZ, and echoes stride.ping_t from STRIDE_PING back on STRIDE_PING_ECHO. It stops after
 * SECONDS (0: never) or on SIGINT/SIGTERM.
 */
#include <lcm/lcm.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>
#include <unistd.h>

#include "stride_joint_command_t.h"
#include "stride_joint_state_t.h"
#include "stride_ping_t.h"

#define MAX_JOINTS 32

static volatile sig_atomic_t stop_requested = 0;
static void on_signal(int sig) { (void)sig; stop_requested = 1; }

static int64_t now_us(void) {
    struct timeval tv;
    gettimeofday(&tv, NULL);
    return (int64_t)tv.tv_sec * 1000000 + tv.tv_usec;
}

typedef struct {
    lcm_t *lcm;
    int n;
    char names[MAX_JOINTS][16];
    double pos[MAX_JOINTS], vel[MAX_JOINTS], target[MAX_JOINTS];
    int64_t commands, pings;
} controller_t;

static void on_command(const lcm_recv_buf_t *rbuf, const char *channel,
                       const stride_joint_command_t *msg, void *user) {
    (void)rbuf; (void)channel;
    controller_t *c = user;
    for (int i = 0; i < msg->num_joints; i++) {
        for (int j = 0; j < c->n; j++) {
            if (strcmp(msg->names[i], c->names[j]) == 0 &&
                msg->modes[i] == STRIDE_JOINT_COMMAND_T_MODE_POSITION) {
                c->target[j] = msg->setpoints[i];
            }
        }
    }
    c->commands++;
}

static void on_ping(const lcm_recv_buf_t *rbuf, const char *channel,
                    const stride_ping_t *msg, void *user) {
    (void)rbuf; (void)channel;
    controller_t *c = user;
    stride_ping_t echo = *msg;
    echo.echoed_by = "legacy-c";
    stride_ping_t_publish(c->lcm, "STRIDE_PING_ECHO", &echo);
    c->pings++;
}

int main(int argc, char **argv) {
    const char *url = NULL;
    int n = 6;
    double rate = 50.0, duration = 0.0;
    int opt;
    while ((opt = getopt(argc, argv, "u:n:r:d:h")) != -1) {
        switch (opt) {
        case 'u': url = optarg; break;
        case 'n': n = atoi(optarg); break;
        case 'r': rate = atof(optarg); break;
        case 'd': duration = atof(optarg); break;
        default:
            fprintf(stderr, "usage: %s [-u URL] [-n JOINTS] [-r HZ] [-d SECONDS]\n", argv[0]);
            return opt == 'h' ? 0 : 2;
        }
    }
    if (n < 1 || n > MAX_JOINTS || rate <= 0) {
        fprintf(stderr, "legacy_controller: bad -n or -r\n");
        return 2;
    }
    controller_t c;
    memset(&c, 0, sizeof c);
    c.n = n;
    for (int i = 0; i < n; i++) snprintf(c.names[i], sizeof c.names[i], "joint%d", i);
    c.lcm = lcm_create(url);
    if (!c.lcm) {
        fprintf(stderr, "legacy_controller: cannot create LCM for %s\n", url ? url : "(default)");
        return 1;
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    stride_joint_command_t_subscribe(c.lcm, "JOINT_COMMAND", on_command, &c);
    stride_ping_t_subscribe(c.lcm, "STRIDE_PING", on_ping, &c);

    char *name_ptrs[MAX_JOINTS];
    double currents[MAX_JOINTS];
    float temps[MAX_JOINTS];
    int32_t faults[MAX_JOINTS];
    for (int i = 0; i < n; i++) {
        name_ptrs[i] = c.names[i];
        currents[i] = 0;
        temps[i] = 30.0f;
        faults[i] = 0;
    }
    int64_t period = (int64_t)(1e6 / rate), start = now_us(), next = start, seq = 0;
    while (!stop_requested && (duration <= 0 || now_us() - start < duration * 1e6)) {
        int64_t wait = next - now_us();
        if (wait > 0) {
            lcm_handle_timeout(c.lcm, (int)(wait / 1000) + 1);
            continue;
        }
        double dt = period / 1e6;
        for (int i = 0; i < n; i++) {
            double err = c.target[i] - c.pos[i], step = 2.0 * dt;
            double move = fabs(err) < step ? err : (err > 0 ? step : -step);
            c.pos[i] += move;
            c.vel[i] = move / dt;
            currents[i] = 0.5 * c.vel[i];
        }
        stride_joint_state_t st;
        memset(&st, 0, sizeof st);
        st.header.utime = now_us();
        st.header.sequence = seq++;
        st.header.frame = "";
        st.num_joints = n;
        st.names = name_ptrs;
        st.positions = c.pos;
        st.velocities = c.vel;
        st.currents = currents;
        st.temperatures = temps;
        st.faults = faults;
        stride_joint_state_t_publish(c.lcm, "JOINT_STATE", &st);
        next += period;
    }
    printf("legacy_controller: %lld commands, %lld pings, %lld states\n",
           (long long)c.commands, (long long)c.pings, (long long)seq);
    lcm_destroy(c.lcm);
    return 0;
}
