/* sphere-sim: the reference firmware (build/firmware/sphere.elf) on a simulated ATmega2560 (simavr, instruction by
 * instruction), with what the board around the chip would do, for the tests (tests/sphere_firmware.py).
 *
 *   sphere-sim FIRMWARE.elf PINLOG
 *
 * stdout, first line:  "port /dev/pts/N f_cpu 16000000"  (the serial port to open; the chip's clock)
 * stdin, one command per line, each answered by one stdout line ("ok ...", "time CYCLE" or "error ..."):
 *   time                                   the simulated time, in clock cycles
 *   temp CELSIUS                           the LM35 on A0 reads this temperature (default 25.00)
 *   led N ok|dark|error                    LED N's current sense and driver fault flag: a good LED, an open
 *                                          circuit (driven, no current), a driver reporting a hard fault
 *   wire no_reply|hang|garbled|slow MS [KEYWORD ...]   a cable fault for those requests (all: no keyword)
 *   wire clear                             no cable faults
 *   unplug                                 the USB cable pulled: the port disappears, the chip runs on
 *   reset power|external|brownout|watchdog the chip resets, with that cause in MCUSR
 *   quit                                   (also: end of stdin, or the parent process dying)
 *
 * PINLOG, one event a line, times in clock cycles (the harness flushes it at least every simulated ms):
 *   P CYCLE LED LEVEL      a PWM pin's level changed (LED 1..10, 0/1; an input pin reads 0: the pull-down)
 *   R CYCLE                the chip's receiver took a request line's "\n" (the firmware's watchdog restarts)
 *   C CYCLE / H CYCLE      a host opened / closed (or vanished from) the port
 *   E CYCLE TEXT           a harness event (reset, temperature, LED state, unplug)
 *
 * Time: simulated time follows the wall clock (the chip sleeps between events; the harness waits for the wall
 * clock, waking early for host input or a command). When the machine is slow the simulation falls behind and
 * catches up; every figure the tests take is on the simulated clock. */
#define _GNU_SOURCE
#include <errno.h>
#include <stdarg.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <time.h>
#include <unistd.h>

#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_time.h"
#include "avr_adc.h"
#include "avr_extint.h"
#include "avr_ioport.h"
#include "avr_uart.h"
#include "bridge.h"

#define N_LEDS 10
#define F_CPU 16000000u
#define SENSE_HOLD_MS 10            /* the board's current sense holds "current seen" this long (peak hold) */
#define SERVICE_CYCLES (F_CPU / 1000)   /* host, commands, sensors: at least once a simulated millisecond */
#define AHEAD_NS 2000000u
#define UCSR0B_ADDR 0xC1                /* ATmega2560 data address of UCSR0B, and its RXEN0 bit */
#define RXEN0_BIT 0x10
#define LOST_BYTE_CYCLES (4 * 1360u)        /* four byte times at 115200 baud (U2X, UBRR 16) */           /* a running (not sleeping) chip waits when it is this far ahead */

typedef struct {
    char port;
    uint8_t bit;
} pin_t;

static const pin_t PWM_PINS[N_LEDS] = {
    {'B', 5}, {'B', 6}, {'E', 3}, {'E', 4}, {'E', 5}, {'H', 3}, {'H', 4}, {'H', 5}, {'L', 3}, {'L', 4},
};
static const pin_t SENSE_PINS[N_LEDS] = {
    {'A', 0}, {'A', 1}, {'A', 2}, {'A', 3}, {'A', 4}, {'A', 5}, {'A', 6}, {'A', 7}, {'C', 0}, {'C', 1},
};
static const pin_t FAULT_PINS[N_LEDS] = {
    {'K', 0}, {'K', 1}, {'K', 2}, {'K', 3}, {'K', 4}, {'K', 5}, {'K', 6}, {'K', 7}, {'C', 2}, {'C', 3},
};

enum led_state { LED_OK, LED_DARK, LED_ERROR };

typedef struct {
    avr_t *avr;
    bridge_t *bridge;
    avr_irq_t *pwm_irq[N_LEDS], *sense_irq[N_LEDS], *fault_irq[N_LEDS], *adc_irq, *uart_in;
    uint8_t ddr[N_LEDS];                    /* the PWM pin is an output (from its port's direction IRQ) */
    int8_t sense_out[N_LEDS], fault_out[N_LEDS];   /* what the harness drives (-1: not yet) */
    int32_t adc_out;
    FILE *log;
    uint64_t wall0_ns;                      /* the wall clock at cycle 0 */
    uint8_t raw[N_LEDS];                    /* the pin's IRQ value */
    uint8_t level[N_LEDS];                  /* the level logged: raw, or 0 while the pin is an input */
    avr_cycle_count_t last_high[N_LEDS];
    enum led_state led[N_LEDS];
    uint32_t temp_mv;
    int rx_idle;                            /* the chip's receiver holds no byte of ours */
    int newline_in_flight;
    avr_cycle_count_t fed_at;
    int io_ready;
    char ctl[512];
    size_t ctl_n;
    int quit;
} sim_t;

static sim_t sim;

static uint64_t wall_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static void log_event(char kind, const char *text)
{
    fprintf(sim.log, "%c %llu%s%s\n", kind, (unsigned long long)sim.avr->cycle, text ? " " : "", text ? text : "");
}

/* -------------------------------------------------------------------------------- the PWM pins */
/* the directions of the PWM pins from the chip's registers (after a reset, which clears them without an IRQ) */
static void read_directions(void)
{
    for (int i = 0; i < N_LEDS; i++) {
        avr_ioport_state_t state;
        if (avr_ioctl(sim.avr, AVR_IOCTL_IOPORT_GETSTATE(PWM_PINS[i].port), &state) == 0)
            sim.ddr[i] = (state.ddr >> PWM_PINS[i].bit) & 1;
    }
}

static void resample_pin(int led)
{
    uint8_t level = sim.raw[led] && sim.ddr[led];
    if (level == sim.level[led])
        return;
    if (sim.level[led])
        sim.last_high[led] = sim.avr->cycle;
    sim.level[led] = level;
    fprintf(sim.log, "P %llu %d %d\n", (unsigned long long)sim.avr->cycle, led + 1, level);
}

static void pin_changed(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    int led = (int)(intptr_t)param;
    sim.raw[led] = value & 1;
    resample_pin(led);
}

static void direction_changed(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    char port = (char)(intptr_t)param;
    for (int i = 0; i < N_LEDS; i++) {
        if (PWM_PINS[i].port == port) {
            sim.ddr[i] = (value >> PWM_PINS[i].bit) & 1;
            resample_pin(i);
        }
    }
}

/* -------------------------------------------------------------------------------- the board's sensors */
static void drive(avr_irq_t *irq, int8_t *was, uint8_t value, int force)
{
    if (!force && *was == (int8_t)value)
        return;
    if (force)
        avr_raise_irq(irq, !value);         /* after a reset the PIN register was cleared: raise it anew */
    avr_raise_irq(irq, value);
    *was = (int8_t)value;
}

static void drive_sensors(int force)
{
    avr_cycle_count_t hold = (avr_cycle_count_t)SENSE_HOLD_MS * (F_CPU / 1000);
    for (int i = 0; i < N_LEDS; i++) {
        uint8_t current = sim.led[i] == LED_OK
            && (sim.level[i] || (sim.last_high[i] && sim.avr->cycle - sim.last_high[i] < hold));
        drive(sim.sense_irq[i], &sim.sense_out[i], current, force);
        drive(sim.fault_irq[i], &sim.fault_out[i], sim.led[i] != LED_ERROR, force);   /* the flag is active low */
    }
    if (force || sim.adc_out != (int32_t)sim.temp_mv) {
        if (force)
            avr_raise_irq(sim.adc_irq, sim.temp_mv + 1);
        avr_raise_irq(sim.adc_irq, sim.temp_mv);
        sim.adc_out = (int32_t)sim.temp_mv;
    }
}

/* -------------------------------------------------------------------------------- the UART */
/* One byte at a time, each when the chip's receiver has taken the one before (its interrupt read UDR0: simavr
 * raises XON), so the moment the chip takes a line's "\n" is known: the 'R' event, when the firmware restarts its
 * watchdog. A byte the receiver never takes (the firmware has not enabled it yet, a reset) counts as lost after
 * a few byte times, as on a real UART. */
static int to_chip(void *ctx, uint8_t byte)
{
    (void)ctx;
    if (!sim.rx_idle && sim.avr->cycle - sim.fed_at < LOST_BYTE_CYCLES)
        return 0;
    sim.rx_idle = 0;
    sim.newline_in_flight = byte == '\n';
    sim.fed_at = sim.avr->cycle;
    avr_raise_irq(sim.uart_in, byte);
    return 1;
}

static void bridge_event(void *ctx, char kind)
{
    (void)ctx;
    log_event(kind, NULL);
}

static void uart_output(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    bridge_from_chip(sim.bridge, (uint8_t)value, wall_ns());
}

static void uart_xon(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    if (!value || sim.rx_idle)
        return;
    sim.rx_idle = 1;                        /* the receiver is empty: the chip took the byte */
    sim.io_ready = 1;                       /* feed the next one now */
    if (sim.newline_in_flight) {
        sim.newline_in_flight = 0;
        log_event('R', NULL);
    }
}

/* -------------------------------------------------------------------------------- pacing */
static void wait_until(uint64_t target_ns)
{
    uint64_t now = wall_ns();
    if (now >= target_ns || sim.io_ready)
        return;
    struct pollfd fds[2] = {{0, POLLIN, 0}, {-1, POLLIN, 0}};
    nfds_t n = 1;
    if (bridge_wants_poll(sim.bridge)) {
        fds[1].fd = bridge_fd(sim.bridge);
        n = 2;
    }
    uint64_t wait = target_ns - now;
    struct timespec ts = {(time_t)(wait / 1000000000u), (long)(wait % 1000000000u)};
    if (ppoll(fds, n, &ts, NULL) > 0)
        sim.io_ready = 1;
}

static uint64_t wall_of(avr_cycle_count_t cycle)
{
    return sim.wall0_ns + avr_cycles_to_nsec(sim.avr, cycle);
}

/* simavr calls this while the chip sleeps until its next event, ``how_long`` cycles ahead */
static void sleep_until_event(avr_t *avr, avr_cycle_count_t how_long)
{
    wait_until(wall_of(avr->cycle + how_long));
}

/* -------------------------------------------------------------------------------- commands */
static void reply(const char *text)
{
    if (printf("%s\n", text) < 0 || fflush(stdout) != 0)
        sim.quit = 1;
}

static void reset_chip(const char *cause)
{
    avr_t *avr = sim.avr;
    avr_regbit_t flag;
    if (!strcmp(cause, "power"))
        flag = avr->reset_flags.porf;
    else if (!strcmp(cause, "external"))
        flag = avr->reset_flags.extrf;
    else if (!strcmp(cause, "brownout"))
        flag = avr->reset_flags.borf;
    else if (!strcmp(cause, "watchdog"))
        flag = avr->reset_flags.wdrf;
    else {
        reply("error reset takes power, external, brownout or watchdog");
        return;
    }
    avr_reset(avr);                         /* every I/O register to 0: the PWM pins are inputs, pulled down */
    avr_regbit_set(avr, flag);
    sim.rx_idle = 1;                        /* a byte on its way is lost with the receiver's FIFO */
    sim.newline_in_flight = 0;
    char text[64];
    snprintf(text, sizeof text, "reset %s", cause);
    log_event('E', text);
    read_directions();
    for (int i = 0; i < N_LEDS; i++)
        resample_pin(i);
    drive_sensors(1);
    reply("ok");
}

static void wire_command(char *args)
{
    static const struct { const char *name; enum wire_fault fault; } NAMES[] = {
        {"no_reply", WIRE_NO_REPLY}, {"hang", WIRE_HANG}, {"garbled", WIRE_GARBLED}, {"slow", WIRE_SLOW},
    };
    char *name = strtok(args, " ");
    if (name && !strcmp(name, "clear")) {
        bridge_clear_faults(sim.bridge);
        reply("ok");
        return;
    }
    char *ms = strtok(NULL, " ");
    char *keywords = strtok(NULL, "");
    for (size_t i = 0; name && ms && i < sizeof NAMES / sizeof NAMES[0]; i++) {
        if (!strcmp(name, NAMES[i].name)) {
            if (bridge_set_fault(sim.bridge, NAMES[i].fault, (uint32_t)strtoul(ms, NULL, 10),
                                 keywords ? keywords : "") == 0) {
                log_event('E', "wire fault");
                reply("ok");
                return;
            }
        }
    }
    reply("error wire takes no_reply|hang|garbled|slow MS [KEYWORD ...] or clear");
}

static void led_command(char *args)
{
    int led = 0;
    char state[16] = "";
    if (sscanf(args, "%d %15s", &led, state) != 2 || led < 1 || led > N_LEDS) {
        reply("error led takes N (1..10) ok|dark|error");
        return;
    }
    enum led_state s = !strcmp(state, "ok") ? LED_OK : !strcmp(state, "dark") ? LED_DARK
        : !strcmp(state, "error") ? LED_ERROR : (enum led_state)-1;
    if ((int)s < 0) {
        reply("error led takes N (1..10) ok|dark|error");
        return;
    }
    sim.led[led - 1] = s;
    char text[48];
    snprintf(text, sizeof text, "led %d %s", led, state);
    log_event('E', text);
    drive_sensors(0);
    reply("ok");
}

static void command(char *line)
{
    char text[96];
    char *args = strchr(line, ' ');
    if (args)
        *args++ = '\0';
    else
        args = line + strlen(line);
    if (!strcmp(line, "time")) {
        for (int i = 0; i < N_LEDS; i++)
            resample_pin(i);
        fflush(sim.log);                    /* the log holds everything up to the time answered */
        snprintf(text, sizeof text, "time %llu", (unsigned long long)sim.avr->cycle);
        reply(text);
    } else if (!strcmp(line, "temp")) {
        double celsius = strtod(args, NULL);
        sim.temp_mv = celsius <= 0 ? 0 : (uint32_t)(celsius * 10.0 + 0.5);    /* LM35: 10 mV per degree */
        snprintf(text, sizeof text, "temp %.2f", celsius);
        log_event('E', text);
        drive_sensors(0);
        reply("ok");
    } else if (!strcmp(line, "led")) {
        led_command(args);
    } else if (!strcmp(line, "wire")) {
        wire_command(args);
    } else if (!strcmp(line, "unplug")) {
        bridge_unplug(sim.bridge);
        log_event('E', "unplug");
        reply("ok");
    } else if (!strcmp(line, "reset")) {
        reset_chip(args);
    } else if (!strcmp(line, "quit")) {
        sim.quit = 1;
    } else {
        reply("error unknown command");
    }
}

static void read_commands(void)
{
    struct pollfd pfd = {0, POLLIN, 0};
    if (poll(&pfd, 1, 0) <= 0)
        return;
    ssize_t n = read(0, sim.ctl + sim.ctl_n, sizeof sim.ctl - 1 - sim.ctl_n);
    if (n <= 0) {
        sim.quit = 1;                       /* the parent closed stdin (or died): the simulation ends */
        return;
    }
    sim.ctl_n += (size_t)n;
    char *nl;
    while ((nl = memchr(sim.ctl, '\n', sim.ctl_n))) {
        *nl = '\0';
        command(sim.ctl);
        size_t used = (size_t)(nl - sim.ctl) + 1;
        memmove(sim.ctl, nl + 1, sim.ctl_n - used);
        sim.ctl_n -= used;
    }
    if (sim.ctl_n == sizeof sim.ctl - 1)
        sim.ctl_n = 0;                      /* a command longer than the buffer: dropped */
}

/* -------------------------------------------------------------------------------- set-up and the run loop */
static void connect_chip(void)
{
    avr_t *avr = sim.avr;
    /* LED 4 and 5 are on INT4 / INT5's pins: simavr polls a low level-triggered pin every cycle (even with the
     * interrupt disabled, as it is here); as edge-triggered it costs nothing and the firmware is the same */
    for (uint8_t n = 0; n < EXTINT_COUNT; n++)
        avr_extint_set_strict_lvl_trig(avr, n, 0);
    for (int i = 0; i < N_LEDS; i++) {
        sim.pwm_irq[i] = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(PWM_PINS[i].port), PWM_PINS[i].bit);
        sim.sense_irq[i] = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(SENSE_PINS[i].port), SENSE_PINS[i].bit);
        sim.fault_irq[i] = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(FAULT_PINS[i].port), FAULT_PINS[i].bit);
        avr_irq_register_notify(sim.pwm_irq[i], pin_changed, (void *)(intptr_t)i);
    }
    sim.adc_irq = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0);
    sim.uart_in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    static const char PORTS[] = "BEHL";
    for (int i = 0; PORTS[i]; i++) {
        avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(PORTS[i]), IOPORT_IRQ_DIRECTION_ALL);
        avr_irq_register_notify(irq, direction_changed, (void *)(intptr_t)PORTS[i]);
    }
    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)AVR_UART_FLAG_STDIO;
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), uart_output, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), uart_xon, NULL);
    for (int i = 0; i < N_LEDS; i++)
        sim.sense_out[i] = sim.fault_out[i] = -1;
    sim.adc_out = -1;
    read_directions();
    drive_sensors(1);
}

/* simavr's messages go to stderr (stdout is the command channel), errors only */
static void quiet_logger(avr_t *avr, const int level, const char *format, va_list ap)
{
    (void)avr;
    if (level <= LOG_ERROR)
        vfprintf(stderr, format, ap);
}

static int start(const char *elf, const char *log_path)
{
    avr_global_logger_set(quiet_logger);
    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(elf, &fw) != 0) {
        fprintf(stderr, "sphere-sim: cannot read %s\n", elf);
        return -1;
    }
    sim.avr = avr_make_mcu_by_name("atmega2560");
    if (!sim.avr || avr_init(sim.avr) != 0)
        return -1;
    avr_load_firmware(sim.avr, &fw);
    sim.avr->frequency = F_CPU;
    sim.avr->vcc = sim.avr->avcc = sim.avr->aref = 5000;
    sim.avr->log = LOG_ERROR;
    sim.avr->sleep = sleep_until_event;
    sim.log = fopen(log_path, "w");
    if (!sim.log) {
        fprintf(stderr, "sphere-sim: cannot write %s\n", log_path);
        return -1;
    }
    fprintf(sim.log, "# sphere-sim pin log: %s, f_cpu %u\n", elf, F_CPU);
    sim.temp_mv = 250;                      /* 25.0 C */
    sim.rx_idle = 1;
    sim.bridge = bridge_open(to_chip, bridge_event, NULL);
    if (!sim.bridge) {
        fprintf(stderr, "sphere-sim: cannot open a pseudo-terminal: %s\n", strerror(errno));
        return -1;
    }
    connect_chip();
    for (int i = 0; i < N_LEDS; i++)
        fprintf(sim.log, "P 0 %d 0\n", i + 1);
    sim.wall0_ns = wall_ns();
    /* the port is offered once the firmware listens (a host opens a real board's port after it booted) */
    while (!(sim.avr->data[UCSR0B_ADDR] & RXEN0_BIT) && sim.avr->cycle < F_CPU / 10) {
        int state = avr_run(sim.avr);
        if (state == cpu_Done || state == cpu_Crashed)
            return -1;
    }
    printf("port %s f_cpu %u\n", bridge_port(sim.bridge), F_CPU);
    fflush(stdout);
    return 0;
}

static void service(void)
{
    static unsigned count;
    uint64_t now = wall_ns();
    bridge_service(sim.bridge, now);
    read_commands();
    if (++count % 8 == 0) {                 /* a reset by the chip's own watchdog clears directions silently */
        read_directions();
        for (int i = 0; i < N_LEDS; i++)
            resample_pin(i);
    }
    drive_sensors(0);
    fflush(sim.log);
    sim.io_ready = 0;
    if (sim.avr->state == cpu_Running && wall_of(sim.avr->cycle) > now + AHEAD_NS)
        wait_until(wall_of(sim.avr->cycle));
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: sphere-sim FIRMWARE.elf PINLOG\n");
        return 2;
    }
    prctl(PR_SET_PDEATHSIG, SIGKILL);       /* never outlive the test that started it */
    signal(SIGPIPE, SIG_IGN);
    if (start(argv[1], argv[2]) != 0)
        return 1;
    avr_cycle_count_t next = 0;
    int status = 0;
    while (!sim.quit) {
        int state = avr_run(sim.avr);
        if (state == cpu_Done || state == cpu_Crashed) {
            log_event('E', state == cpu_Crashed ? "crashed" : "stopped");
            fprintf(stderr, "sphere-sim: the chip %s\n", state == cpu_Crashed ? "crashed" : "stopped");
            status = 3;
            break;
        }
        if (sim.avr->cycle >= next || sim.io_ready) {
            service();
            next = sim.avr->cycle + SERVICE_CYCLES;
        }
    }
    fflush(sim.log);
    fclose(sim.log);
    return status;
}
