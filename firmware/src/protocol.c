/* The request interpreter (protocol.h). Framing, tokens, argument checks, the order of the checks and every
 * reply's bytes follow drivers/led_sphere/protocol.py (parse_request, Command.parse_args, render_error) and the
 * emulator's commands (drivers/virtual/sphere_emulator.py); tests/drivers/test_sphere_protocol.py sends the same
 * requests to both and compares the replies byte for byte. */
#include <stdlib.h>
#include <string.h>
#include <avr/pgmspace.h>
#include "board.h"
#include "protocol.h"
#include "protocol_table.h"
#include "serial.h"
#include "sphere.h"

#define MAX_TOKENS (PROTO_MAX_CHANNELS + 2)     /* enough for any request whose argument count is right */

static char line[PROTO_MAX_REQUEST_BYTES];
static uint8_t line_len, discarding, pending;
static char out[PROTO_MAX_REPLY_BYTES];
static uint8_t out_len;
static const char *serial_number;

typedef struct {
    uint8_t start[MAX_TOKENS];
    uint8_t len[MAX_TOKENS];
    uint8_t count;                          /* all tokens, also those not stored */
} tokens_t;

enum { DONE, DEFER };

void protocol_init(const char *serial)
{
    serial_number = serial;
}

/* -------------------------------------------------------------------------------- reply text */
static void put_c(char c)
{
    if (out_len < PROTO_MAX_REPLY_BYTES - 1)
        out[out_len++] = c;
}

static void put_s(const char *s)
{
    while (*s)
        put_c(*s++);
}

static void put_p(const char *s)            /* PROGMEM */
{
    char c;
    while ((c = (char)pgm_read_byte(s++)))
        put_c(c);
}

static void put_u(uint32_t v)
{
    char digits[11];
    put_s(ultoa(v, digits, 10));
}

static void put_ms_as_s(uint32_t ms)        /* 12.500 */
{
    put_u(ms / 1000);
    put_c('.');
    uint16_t frac = (uint16_t)(ms % 1000);
    put_c((char)('0' + frac / 100));
    put_c((char)('0' + frac / 10 % 10));
    put_c((char)('0' + frac % 10));
}

static void put_centi(int16_t centi, uint8_t decimals)    /* 27.31 (2 decimals) or 27.3 (1, rounded) */
{
    uint16_t a = (uint16_t)(centi < 0 ? -centi : centi);
    if (decimals == 1)
        a = (uint16_t)((a + 5) / 10);
    uint16_t scale = decimals == 1 ? 10 : 100;
    if (centi < 0 && a)
        put_c('-');
    put_u(a / scale);
    put_c('.');
    if (decimals == 2)
        put_c((char)('0' + a / 10 % 10));
    put_c((char)('0' + a % 10));
}

static void ok(const proto_command_t *cmd)
{
    out_len = 0;
    put_s("OK ");
    put_p((const char *)pgm_read_ptr(&cmd->reply));
}

static void err(uint8_t code)
{
    out_len = 0;
    put_s("ERR ");
    put_u(code);
    put_c(' ');
}

static void err_p(uint8_t code, const char *message)      /* message in PROGMEM */
{
    err(code);
    put_p(message);
}

/* -------------------------------------------------------------------------------- parsing */
static uint8_t is_space(uint8_t c)          /* Python's str.split(): space, \t \n \v \f \r, \x1c..\x1f */
{
    return c == ' ' || (c >= 9 && c <= 13) || (c >= 28 && c <= 31);
}

static void tokenize(tokens_t *t, uint8_t n)
{
    t->count = 0;
    uint8_t i = 0;
    while (i < n) {
        while (i < n && is_space((uint8_t)line[i]))
            i++;
        if (i >= n)
            break;
        uint8_t start = i;
        while (i < n && !is_space((uint8_t)line[i]))
            i++;
        if (t->count < MAX_TOKENS) {
            t->start[t->count] = start;
            t->len[t->count] = (uint8_t)(i - start);
        }
        t->count++;
    }
}

static char upper(char c)
{
    return (c >= 'a' && c <= 'z') ? (char)(c - 'a' + 'A') : c;
}

static int8_t find_command(const tokens_t *t)
{
    const char *word = line + t->start[0];
    for (uint8_t id = 0; id < CMD_COUNT; id++) {
        const char *kw = (const char *)pgm_read_ptr(&PROTO_COMMANDS[id].keyword);
        if (strlen_P(kw) != t->len[0])
            continue;
        uint8_t k = 0;
        while (k < t->len[0] && upper(word[k]) == (char)pgm_read_byte(kw + k))
            k++;
        if (k == t->len[0])
            return (int8_t)id;
    }
    return -1;
}

static void unknown_command(const tokens_t *t)
{
    err(ERR_UNKNOWN_COMMAND);
    put_s("unknown command ");
    for (uint8_t k = 0; k < t->len[0] && k < 16; k++) {
        char c = line[t->start[0] + k];
        put_c(c >= ' ' && c <= '~' ? c : '?');
    }
}

static uint8_t is_number(const tokens_t *t, uint8_t i)    /* 1..7 decimal digits */
{
    if (t->len[i] > 7)
        return 0;
    for (uint8_t k = 0; k < t->len[i]; k++)
        if (line[t->start[i] + k] < '0' || line[t->start[i] + k] > '9')
            return 0;
    return 1;
}

static uint32_t number(const tokens_t *t, uint8_t i)
{
    uint32_t v = 0;
    for (uint8_t k = 0; k < t->len[i]; k++)
        v = v * 10 + (uint32_t)(line[t->start[i] + k] - '0');
    return v;
}

/* Command.parse_args: the argument count, then field by field: every token a number (ERR 3), every value in
 * range (ERR 4). Fills values (the list field's values from values[nargs - 1] on); 0 when an ERR was written. */
static uint8_t parse_args(const proto_command_t *cmd, const tokens_t *t, uint32_t *values, uint8_t *nvalues)
{
    uint8_t nargs = pgm_read_byte(&cmd->nargs), list = pgm_read_byte(&cmd->list);
    uint8_t given = (uint8_t)(t->count - 1), fixed = (uint8_t)(nargs - (list ? 1 : 0));
    if (given < nargs || (!list && given > nargs) || (list && given - fixed > PROTO_MAX_CHANNELS)) {
        err_p(ERR_ARGUMENT_COUNT, (const char *)pgm_read_ptr(&cmd->usage));
        return 0;
    }
    *nvalues = 0;
    for (uint8_t f = 0; f < nargs; f++) {
        proto_field_t field;
        memcpy_P(&field, &PROTO_FIELDS[pgm_read_byte(&cmd->fields[f])], sizeof field);
        uint8_t first = (uint8_t)(1 + f), last = (list && f == nargs - 1) ? given : first;
        for (uint8_t i = first; i <= last; i++) {
            if (!is_number(t, i)) {
                err_p(ERR_NOT_A_NUMBER, field.name);
                put_s(" must be an unsigned integer");
                return 0;
            }
        }
        for (uint8_t i = first; i <= last; i++) {
            uint32_t v = number(t, i);
            if (v < field.lo || v > field.hi) {
                err_p(ERR_OUT_OF_RANGE, field.name);
                put_s(" outside ");
                put_p(field.range);
                return 0;
            }
            values[(*nvalues)++] = v;
        }
    }
    return 1;
}

/* -------------------------------------------------------------------------------- commands */
static uint8_t led_ok(uint32_t led)         /* the emulator's _led(): the table allows 16, the sphere has 10 */
{
    if (led <= N_LEDS)
        return 1;
    err(ERR_OUT_OF_RANGE);
    put_s("led outside 1..");
    put_u(N_LEDS);
    return 0;
}

static void led_fault(uint8_t led)
{
    err(ERR_LED_FAULT);
    put_s("LED ");
    put_u(led);
    put_s(" driver fault");
}

static void light_on(const proto_command_t *cmd, uint8_t with_limit, uint32_t value)
{
    if (sphere_light_on(with_limit, value)) {
        err(ERR_OVER_TEMPERATURE);
        put_s("temperature ");
        put_centi(sphere_temperature(), 1);
        put_s(" C, light stays off");
        return;
    }
    ok(cmd);
    put_c(' ');
    put_u(value);
}

static void put_levels(const uint16_t *pwm)
{
    for (uint8_t i = 0; i < N_LEDS; i++) {
        put_c(' ');
        put_u(pwm[i]);
    }
}

static uint8_t status(const proto_command_t *cmd)
{
    int32_t mask = sphere_fault_mask();
    if (mask < 0)
        return DEFER;
    sphere_status_t s;
    sphere_status(&s);
    ok(cmd);
    put_s(" light=");
    put_u(s.light);
    put_s(" ontime=");
    put_ms_as_s(s.ontime_ms);
    put_s(" temp=");
    put_centi(s.temp_centi, 2);
    put_s(" wdog=");
    put_u(s.wdog_ms);
    put_s(" trip=");
    put_u(s.trip);
    put_s(" fault=");
    put_u((uint32_t)mask);
    return DONE;
}

static uint8_t settable(const proto_command_t *cmd, uint8_t id, const uint32_t *v, uint8_t n)
{
    uint8_t failed;
    switch (id) {
    case CMD_SET_LEVEL:
        if (!led_ok(v[0]))
            return DONE;
        if ((failed = sphere_set_level((uint8_t)v[0], (uint16_t)v[1]))) {
            led_fault(failed);
            return DONE;
        }
        ok(cmd);
        put_c(' ');
        put_u(v[0]);
        put_c(' ');
        put_u(v[1]);
        return DONE;
    case CMD_SET_LEVELS:
        if (n != N_LEDS) {
            err(ERR_ARGUMENT_COUNT);
            put_s("LEVELS takes exactly ");
            put_u(N_LEDS);
            put_s(" values");
            return DONE;
        }
        if ((failed = sphere_set_levels(v))) {
            led_fault(failed);
            return DONE;
        }
        ok(cmd);
        for (uint8_t i = 0; i < N_LEDS; i++) {
            put_c(' ');
            put_u(v[i]);
        }
        return DONE;
    case CMD_ALL_OFF:
        sphere_all_off();
        ok(cmd);
        return DONE;
    case CMD_SET_LIGHT:
        if (v[0])
            light_on(cmd, 0, 1);
        else {
            sphere_light_off();
            ok(cmd);
            put_s(" 0");
        }
        return DONE;
    case CMD_LIGHT_ON_FOR:
        light_on(cmd, 1, v[0]);
        return DONE;
    case CMD_SET_WATCHDOG:
        sphere_set_watchdog(v[0]);
        ok(cmd);
        put_c(' ');
        put_u(v[0]);
        return DONE;
    }
    return DONE;
}

static uint8_t query(const proto_command_t *cmd, uint8_t id, const uint32_t *v)
{
    sphere_status_t s;
    int32_t mask = 0;
    if (id == CMD_STATUS)
        return status(cmd);
    if (id == CMD_FAULTS && (mask = sphere_fault_mask()) < 0)
        return DEFER;
    if ((id == CMD_GET_LEVEL || id == CMD_LED_ON_TIME) && !led_ok(v[0]))
        return DONE;
    sphere_status(&s);
    ok(cmd);
    switch (id) {
    case CMD_IDENTIFY:
        put_s(" " SPHERE_MODEL " " PROTO_FIRMWARE_VERSION " ");
        put_s(serial_number);
        break;
    case CMD_CHANNELS:
        put_c(' ');
        put_u(N_LEDS);
        break;
    case CMD_GET_LEVEL:
        put_c(' ');
        put_u(v[0]);
        put_c(' ');
        put_u(s.pwm[v[0] - 1]);
        break;
    case CMD_GET_LEVELS:
        put_levels(s.pwm);
        break;
    case CMD_GET_LIGHT:
        put_c(' ');
        put_u(s.light);
        break;
    case CMD_TEMPERATURE:
        put_c(' ');
        put_centi(s.temp_centi, 2);
        break;
    case CMD_ON_TIME:
        put_c(' ');
        put_ms_as_s(s.ontime_ms);
        break;
    case CMD_LED_ON_TIME:
        put_c(' ');
        put_u(v[0]);
        put_c(' ');
        put_ms_as_s(sphere_led_on_time((uint8_t)(v[0] - 1)));
        break;
    case CMD_GET_WATCHDOG:
        put_c(' ');
        put_u(s.wdog_ms);
        break;
    case CMD_FAULTS:
        put_c(' ');
        put_u((uint32_t)mask);
        break;
    }                                       /* CMD_PING: the keyword alone */
    return DONE;
}

/* One request line (terminator stripped) -> the reply in out[]; DEFER: ask again later (nothing was changed). */
static uint8_t handle(uint8_t n)
{
    for (uint8_t i = 0; i < n; i++) {
        if ((uint8_t)line[i] >= 0x80) {
            err(ERR_UNKNOWN_COMMAND);
            put_s("request is not ASCII");
            return DONE;
        }
    }
    tokens_t t;
    tokenize(&t, n);
    if (t.count == 0) {
        err(ERR_UNKNOWN_COMMAND);
        put_s("empty request");
        return DONE;
    }
    int8_t id = find_command(&t);
    if (id < 0) {
        unknown_command(&t);
        return DONE;
    }
    const proto_command_t *cmd = &PROTO_COMMANDS[id];
    uint32_t values[PROTO_MAX_CHANNELS];
    uint8_t nvalues;
    if (!parse_args(cmd, &t, values, &nvalues))
        return DONE;
    if (id == CMD_SET_LEVEL || id == CMD_SET_LEVELS || id == CMD_ALL_OFF || id == CMD_SET_LIGHT
            || id == CMD_LIGHT_ON_FOR || id == CMD_SET_WATCHDOG)
        return settable(cmd, (uint8_t)id, values, nvalues);
    return query(cmd, (uint8_t)id, values);
}

static void send_reply(void)
{
    out[out_len++] = '\n';                  /* put_c keeps the last byte free for it */
    serial_write(out, out_len);
}

/* -------------------------------------------------------------------------------- framing */
uint8_t protocol_poll(void)
{
    if (pending) {                          /* a request waiting for the current sense */
        if (handle(line_len) == DEFER)
            return 1;
        send_reply();
        pending = 0;
        line_len = 0;
    }
    while (serial_available()) {
        char c = (char)serial_read();
        if (c == '\n') {
            if (discarding) {
                discarding = 0;
                continue;
            }
            uint8_t n = line_len;
            while (n && line[n - 1] == '\r')
                n--;
            line_len = n;
            if (handle(n) == DEFER) {
                pending = 1;
                return 1;
            }
            send_reply();
            line_len = 0;
        } else if (!discarding) {
            line[line_len++] = c;
            if (line_len >= PROTO_MAX_REQUEST_BYTES) {
                err(ERR_LINE_TOO_LONG);
                put_s("line longer than ");
                put_u(PROTO_MAX_REQUEST_BYTES);
                put_s(" bytes");
                send_reply();
                discarding = 1;
                line_len = 0;
            }
        }
    }
    return 0;
}
