/* The sphere's state and its own safety (sphere.h). The behaviour is the protocol's
 * (docs/led-sphere-protocol.md), request for request as drivers/virtual/sphere_emulator.py does it; what only a
 * real chip has (a measured temperature, current sense, resets) is in firmware/README.md.
 *
 * Time is the tick's millisecond count. A limit counts from the tick at or before the moment it starts (the
 * request's last byte, the switch-on), so the light is off at most the limit after that moment: never later. */
#include <string.h>
#include <avr/io.h>
#include <avr/interrupt.h>
#include <util/atomic.h>
#include "inputs.h"
#include "outputs.h"
#include "protocol_table.h"
#include "sphere.h"

static volatile uint32_t now_ms;
static volatile uint32_t last_request_ms;   /* the watchdog counts from here */
static uint16_t pwm[N_LEDS];
static uint8_t light;
static uint8_t trip;
static uint8_t limit_armed;                 /* ON <ms>: off_at holds */
static uint8_t any_level;                   /* a level is non-zero: the watchdog guards it even with the light off */
static uint32_t light_since;
static uint32_t off_at;
static uint32_t wdog_ms = PROTO_DEFAULT_WATCHDOG_MS;
static uint16_t driven;                     /* bit per LED: light on and level > 0 */
static uint32_t driven_since[N_LEDS];
static int16_t temp_centi;

/* -------------------------------------------------------------------------------- switching (interrupts off) */
static void refresh_outputs(void)
{
    uint16_t now_driven = 0;
    any_level = 0;
    for (uint8_t i = 0; i < N_LEDS; i++) {
        if (pwm[i])
            any_level = 1;
        if (light && pwm[i])
            now_driven |= (uint16_t)(1U << i);
    }
    for (uint8_t i = 0; i < N_LEDS; i++)
        if ((now_driven & ~driven) & (1U << i))
            driven_since[i] = now_ms;
    driven = now_driven;
    outputs_apply(light, pwm);
}

static void go_dark(uint8_t zero_levels, uint8_t set_trip)
{
    outputs_dark();                         /* first: the pins are low from here on */
    light = 0;
    limit_armed = 0;
    driven = 0;
    if (zero_levels) {
        memset(pwm, 0, sizeof pwm);
        any_level = 0;
    }
    if (set_trip)
        trip = 1;
}

/* -------------------------------------------------------------------------------- the tick */
ISR(TIMER0_COMPA_vect)
{
    uint32_t t = now_ms + 1;
    now_ms = t;
    if ((light || any_level) && t - last_request_ms >= wdog_ms)
        go_dark(1, 1);                      /* watchdog: no request for WDOG ms */
    if (light && limit_armed && (int32_t)(t - off_at) >= 0)
        go_dark(0, 1);                      /* ON <ms>: its limit, counted from when the light came on */
    int16_t centi;
    if (inputs_tick(&centi)) {
        temp_centi = centi;
        if (light && centi > OVER_TEMPERATURE_CENTI)
            go_dark(0, 0);                  /* over temperature: off, levels kept, no trip (as the emulator) */
    }
}

void sphere_init(uint8_t tripped, int16_t centi)
{
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        go_dark(1, 0);
        trip = tripped;
        temp_centi = centi;
        wdog_ms = PROTO_DEFAULT_WATCHDOG_MS;
    }
    TCCR0A = _BV(WGM01);                    /* CTC */
    OCR0A = TICK_OCR;
    TIMSK0 = _BV(OCIE0A);
    TCCR0B = _BV(CS01) | _BV(CS00);         /* 16 MHz / 64 / 250 = 1 kHz */
}

void sphere_request_seen(void)
{
    last_request_ms = now_ms;               /* called from the receive interrupt: no other interrupt runs now */
}

/* -------------------------------------------------------------------------------- requests (main loop) */
uint8_t sphere_set_level(uint8_t led, uint16_t value)
{
    if (value && inputs_driver_fault(led - 1))
        return led;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        pwm[led - 1] = value;
        refresh_outputs();
    }
    return 0;
}

uint8_t sphere_set_levels(const uint32_t *values)
{
    for (uint8_t i = 0; i < N_LEDS; i++)
        if (values[i] && inputs_driver_fault(i))
            return (uint8_t)(i + 1);
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        for (uint8_t i = 0; i < N_LEDS; i++)
            pwm[i] = (uint16_t)values[i];
        refresh_outputs();
    }
    return 0;
}

void sphere_all_off(void)
{
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        memset(pwm, 0, sizeof pwm);
        refresh_outputs();
    }
}

uint8_t sphere_light_on(uint8_t with_limit, uint32_t limit_ms)
{
    uint8_t refused = 0;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        if (temp_centi > OVER_TEMPERATURE_CENTI) {
            refused = 1;
        } else {
            trip = 0;
            if (!light) {
                light = 1;
                light_since = now_ms;
            }
            if (with_limit) {               /* from when it came on: a repeated ON never extends past that */
                off_at = light_since + limit_ms;
                limit_armed = 1;
            }
            refresh_outputs();
        }
    }
    return refused;
}

void sphere_light_off(void)
{
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        light = 0;
        limit_armed = 0;
        refresh_outputs();
    }
}

void sphere_set_watchdog(uint32_t ms)
{
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        wdog_ms = ms;
    }
}

/* -------------------------------------------------------------------------------- views */
void sphere_status(sphere_status_t *out)
{
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        memcpy(out->pwm, pwm, sizeof pwm);
        out->light = light;
        out->trip = trip;
        out->ontime_ms = light ? now_ms - light_since : 0;
        out->wdog_ms = wdog_ms;
        out->temp_centi = temp_centi;
    }
}

int16_t sphere_temperature(void)
{
    int16_t t;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        t = temp_centi;
    }
    return t;
}

/* Driven and, as far as the sensors tell, emitting: no driver fault, and current once the sense has settled. */
static uint8_t emitting(uint8_t i, uint32_t now)
{
    if (!(driven & (1U << i)) || inputs_driver_fault(i))
        return 0;
    if (pwm[i] < SENSE_MIN_PWM || now - driven_since[i] < SENSE_SETTLE_MS)
        return 1;
    return inputs_current(i);
}

uint32_t sphere_led_on_time(uint8_t led)
{
    uint32_t ms = 0;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        if (emitting(led, now_ms))
            ms = now_ms - driven_since[led];
    }
    return ms;
}

int32_t sphere_fault_mask(void)
{
    int32_t mask = 0;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        for (uint8_t i = 0; i < N_LEDS; i++) {
            if (!(driven & (1U << i)))
                continue;                   /* a channel that is not driven cannot show a fault */
            if (inputs_driver_fault(i)) {
                mask |= 1L << i;
            } else if (pwm[i] >= SENSE_MIN_PWM) {
                if (now_ms - driven_since[i] < SENSE_SETTLE_MS)
                    mask = -1;              /* not yet known: ask again after the next tick */
                else if (!inputs_current(i))
                    mask |= 1L << i;
            }
            if (mask < 0)
                break;
        }
    }
    return mask;
}
