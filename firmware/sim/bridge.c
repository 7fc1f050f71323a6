/* The simulated chip's USB cable (bridge.h).
 *
 * The harness does not hold the pty's slave side open: the master then reads POLLHUP exactly while no host has
 * the port open, so the moment a host vanishes (its process killed, the port closed) is logged ('H'). Bytes the
 * chip sends while no host holds the port are lost, as on a USB serial adapter nobody reads.
 *
 * Host bytes go to the chip a line at a time (a line longer than LINE_MAX goes as it is, in pieces), so that a
 * wire fault can pick requests by keyword, as the emulator's inject(..., keywords=...) does; each line that
 * reaches the chip queues what happens to its reply (exactly one reply line per request line). The harness takes
 * the bytes as fast as the chip's receiver does (to_chip returns 0 until it has room). */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>
#include "bridge.h"

#define LINE_MAX 256
#define FEED_MAX 4096
#define POLICIES 64
#define DELAYED 32
#define N_FAULTS 4
#define KEYWORDS_MAX 160

typedef struct {
    int faults;             /* wire_fault bits for this reply */
    uint32_t delay_ms;
} policy_t;

typedef struct {
    uint64_t due_ns;
    uint8_t data[LINE_MAX];
    uint16_t n;
} delayed_t;

typedef struct {
    int active;
    uint32_t delay_ms;
    char keywords[KEYWORDS_MAX];    /* " ON LIGHT " (spaces around each), or "" for every request */
} fault_rule_t;

struct bridge {
    int master;
    int connected;
    char port[64];
    bridge_to_chip_fn to_chip;
    bridge_event_fn event;
    void *ctx;
    uint8_t line[LINE_MAX];             /* host -> chip, the line being assembled */
    uint16_t line_n;
    uint8_t feed[FEED_MAX];             /* host -> chip, waiting for room in the chip's FIFO */
    uint16_t feed_head, feed_n;
    policy_t policies[POLICIES];        /* one per request line that went in, oldest first */
    uint8_t policy_head, policy_n;
    uint8_t reply[LINE_MAX];            /* chip -> host, the reply line being assembled */
    uint16_t reply_n;
    delayed_t delayed[DELAYED];
    fault_rule_t rules[N_FAULTS];
    uint32_t rng;
};

static const int FAULT_BITS[N_FAULTS] = {WIRE_NO_REPLY, WIRE_HANG, WIRE_GARBLED, WIRE_SLOW};

bridge_t *bridge_open(bridge_to_chip_fn to_chip, bridge_event_fn event, void *ctx)
{
    bridge_t *b = calloc(1, sizeof *b);
    int slave;
    if (!b || openpty(&b->master, &slave, b->port, NULL, NULL) != 0) {
        free(b);
        return NULL;
    }
    struct termios tio;
    if (tcgetattr(slave, &tio) == 0) {
        cfmakeraw(&tio);                /* no echo, no line discipline: bytes pass verbatim */
        tcsetattr(slave, TCSANOW, &tio);
    }
    close(slave);
    fcntl(b->master, F_SETFL, fcntl(b->master, F_GETFL) | O_NONBLOCK);
    b->to_chip = to_chip;
    b->event = event;
    b->ctx = ctx;
    b->rng = 38;
    return b;
}

const char *bridge_port(const bridge_t *b)
{
    return b->port;
}

int bridge_fd(const bridge_t *b)
{
    return b->master;
}

int bridge_wants_poll(const bridge_t *b)
{
    return b->master >= 0 && b->connected;
}

/* -------------------------------------------------------------------------------- faults */
int bridge_set_fault(bridge_t *b, enum wire_fault fault, uint32_t delay_ms, const char *keywords)
{
    for (int i = 0; i < N_FAULTS; i++) {
        if (FAULT_BITS[i] != (int)fault)
            continue;
        fault_rule_t *r = &b->rules[i];
        size_t n = strlen(keywords);
        if (n + 3 > KEYWORDS_MAX)
            return -1;
        r->keywords[0] = '\0';
        if (n) {
            r->keywords[0] = ' ';
            memcpy(r->keywords + 1, keywords, n);
            r->keywords[n + 1] = ' ';
            r->keywords[n + 2] = '\0';
        }
        r->delay_ms = delay_ms;
        r->active = 1;
        return 0;
    }
    return -1;
}

void bridge_clear_faults(bridge_t *b)
{
    memset(b->rules, 0, sizeof b->rules);
}

static int is_space(uint8_t c)
{
    return c == ' ' || (c >= 9 && c <= 13) || (c >= 28 && c <= 31);
}

/* The faults that apply to a request line: its keyword is what precedes the first space, stripped and upper
 * cased (the emulator's _active_faults). */
static policy_t classify(const bridge_t *b, const uint8_t *line, uint16_t n)
{
    char keyword[40];
    uint16_t end = 0, start = 0, k = 0;
    while (end < n && line[end] != ' ')
        end++;
    while (start < end && is_space(line[start]))
        start++;
    while (end > start && is_space(line[end - 1]))
        end--;
    keyword[k++] = ' ';
    for (uint16_t i = start; i < end && k < sizeof keyword - 2; i++)
        keyword[k++] = (char)((line[i] >= 'a' && line[i] <= 'z') ? line[i] - 32 : line[i]);
    keyword[k++] = ' ';
    keyword[k] = '\0';
    policy_t p = {0, 0};
    for (int i = 0; i < N_FAULTS; i++) {
        const fault_rule_t *r = &b->rules[i];
        if (r->active && (!r->keywords[0] || strstr(r->keywords, keyword))) {
            p.faults |= FAULT_BITS[i];
            if (FAULT_BITS[i] == WIRE_SLOW)
                p.delay_ms = r->delay_ms;
        }
    }
    return p;
}

/* -------------------------------------------------------------------------------- host -> chip */
static void feed_push(bridge_t *b, const uint8_t *data, uint16_t n)
{
    for (uint16_t i = 0; i < n && b->feed_n < FEED_MAX; i++, b->feed_n++)
        b->feed[(b->feed_head + b->feed_n) % FEED_MAX] = data[i];
}

static void line_done(bridge_t *b)
{
    policy_t p = classify(b, b->line, b->line_n);
    if (!(p.faults & WIRE_HANG)) {
        feed_push(b, b->line, b->line_n);
        if (b->policy_n < POLICIES) {
            b->policies[(b->policy_head + b->policy_n) % POLICIES] = p;
            b->policy_n++;
        }
    }
    b->line_n = 0;
}

static void from_host(bridge_t *b, const uint8_t *data, ssize_t n)
{
    for (ssize_t i = 0; i < n; i++) {
        b->line[b->line_n++] = data[i];
        if (data[i] == '\n')
            line_done(b);
        else if (b->line_n == LINE_MAX) {       /* far too long for a request: pass it on as it is */
            feed_push(b, b->line, b->line_n);
            b->line_n = 0;
        }
    }
}

static void feed_chip(bridge_t *b)
{
    while (b->feed_n) {
        uint8_t byte = b->feed[b->feed_head];
        if (!b->to_chip(b->ctx, byte))
            return;                             /* the chip's FIFO is full: the rest waits */
        b->feed_head = (uint16_t)((b->feed_head + 1) % FEED_MAX);
        b->feed_n--;
    }
}

static void read_host(bridge_t *b)
{
    struct pollfd pfd = {b->master, POLLIN, 0};
    if (poll(&pfd, 1, 0) < 0)
        return;
    int connected = !(pfd.revents & POLLHUP);
    if (connected != b->connected) {
        b->connected = connected;
        b->event(b->ctx, connected ? 'C' : 'H');
        if (!connected)
            b->line_n = 0;                      /* a half line from a host that went away is gone too */
    }
    if (!(pfd.revents & POLLIN))
        return;
    uint8_t buf[512];
    ssize_t n = read(b->master, buf, sizeof buf);
    if (n > 0)
        from_host(b, buf, n);
}

/* -------------------------------------------------------------------------------- chip -> host */
static void to_host(bridge_t *b, const uint8_t *data, uint16_t n)
{
    if (b->master < 0 || !b->connected)
        return;                                 /* nobody holds the port: the bytes are lost */
    ssize_t done = write(b->master, data, n);
    (void)done;                                 /* a host that stops reading loses the reply, as on a real port */
}

static void garble(bridge_t *b, uint8_t *data, uint16_t n)
{
    for (uint16_t i = 0; i + 1 < n; i++) {      /* the terminator stays: the host sees one bad line */
        b->rng = b->rng * 1103515245u + 12345u;
        if (i == 0 || (b->rng >> 16) % 100 < 35)
            data[i] = (uint8_t)(0x80 | (b->rng >> 8));
    }
}

static void reply_done(bridge_t *b, uint64_t wall_ns)
{
    policy_t p = {0, 0};
    if (b->policy_n) {
        p = b->policies[b->policy_head];
        b->policy_head = (uint8_t)((b->policy_head + 1) % POLICIES);
        b->policy_n--;
    }
    if (p.faults & WIRE_NO_REPLY)
        return;
    if (p.faults & WIRE_GARBLED)
        garble(b, b->reply, b->reply_n);
    if (!(p.faults & WIRE_SLOW)) {
        to_host(b, b->reply, b->reply_n);
        return;
    }
    for (int i = 0; i < DELAYED; i++) {
        if (b->delayed[i].n == 0) {
            b->delayed[i].due_ns = wall_ns + (uint64_t)p.delay_ms * 1000000u;
            memcpy(b->delayed[i].data, b->reply, b->reply_n);
            b->delayed[i].n = b->reply_n;
            return;
        }
    }
}

void bridge_from_chip(bridge_t *b, uint8_t byte, uint64_t wall_ns)
{
    if (b->reply_n < LINE_MAX)
        b->reply[b->reply_n++] = byte;
    if (byte == '\n' || b->reply_n == LINE_MAX) {
        reply_done(b, wall_ns);
        b->reply_n = 0;
    }
}

void bridge_service(bridge_t *b, uint64_t wall_ns)
{
    if (b->master < 0)
        return;
    read_host(b);
    feed_chip(b);
    for (int i = 0; i < DELAYED; i++) {
        if (b->delayed[i].n && b->delayed[i].due_ns <= wall_ns) {
            to_host(b, b->delayed[i].data, b->delayed[i].n);
            b->delayed[i].n = 0;
        }
    }
}

void bridge_unplug(bridge_t *b)
{
    if (b->master >= 0)
        close(b->master);
    b->master = -1;
    if (b->connected)
        b->event(b->ctx, 'H');
    b->connected = 0;
    b->feed_n = 0;
    b->line_n = 0;
}
