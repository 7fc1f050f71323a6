/* The 10 PWM outputs on the ATmega2560's 16-bit timers 1, 3, 4 and 5 (board.h has the pin map).
 *
 * A timer runs only while the light is on and one of its channels is between 0 and full level; starting it
 * begins a PWM period at once (TCNT = TOP: the next clock is BOTTOM, where the outputs are set). A channel at 0
 * or at full level is its port bit (compare output disconnected). Switching dark disconnects every compare output
 * and clears the port bits: the pins are low from that instruction on, whatever the timers do next. */
#include <avr/io.h>
#include "outputs.h"

typedef struct {
    volatile uint8_t *tccra;
    volatile uint16_t *ocr;
    volatile uint8_t *port;
    volatile uint8_t *ddr;
    uint8_t com;            /* COMnx1 in TCCRnA: clear on compare match, set at BOTTOM (non-inverting) */
    uint8_t pin;            /* the pin's bit in its port */
    uint8_t timer;          /* index into TIMERS */
} channel_t;

typedef struct {
    volatile uint8_t *tccra;
    volatile uint8_t *tccrb;
    volatile uint16_t *tcnt;
    volatile uint16_t *icr;
} pwm_timer_t;

#define N_TIMERS 4
/* mode 14 (fast PWM, TOP = ICRn): WGMn1 in TCCRnA, WGMn3 and WGMn2 in TCCRnB (same bit numbers in all four) */
#define TCCRA_IDLE _BV(WGM11)
#define TCCRB_STOPPED (_BV(WGM13) | _BV(WGM12))
#define TCCRB_RUNNING (TCCRB_STOPPED | _BV(CS10))      /* no prescaler: 16 MHz */

static const pwm_timer_t TIMERS[N_TIMERS] = {
    {&TCCR1A, &TCCR1B, &TCNT1, &ICR1},
    {&TCCR3A, &TCCR3B, &TCNT3, &ICR3},
    {&TCCR4A, &TCCR4B, &TCNT4, &ICR4},
    {&TCCR5A, &TCCR5B, &TCNT5, &ICR5},
};

static const channel_t CHANNELS[N_LEDS] = {
    {&TCCR1A, &OCR1A, &PORTB, &DDRB, _BV(COM1A1), _BV(PB5), 0},   /* LED 1  D11 */
    {&TCCR1A, &OCR1B, &PORTB, &DDRB, _BV(COM1B1), _BV(PB6), 0},   /* LED 2  D12 */
    {&TCCR3A, &OCR3A, &PORTE, &DDRE, _BV(COM3A1), _BV(PE3), 1},   /* LED 3  D5 */
    {&TCCR3A, &OCR3B, &PORTE, &DDRE, _BV(COM3B1), _BV(PE4), 1},   /* LED 4  D2 */
    {&TCCR3A, &OCR3C, &PORTE, &DDRE, _BV(COM3C1), _BV(PE5), 1},   /* LED 5  D3 */
    {&TCCR4A, &OCR4A, &PORTH, &DDRH, _BV(COM4A1), _BV(PH3), 2},   /* LED 6  D6 */
    {&TCCR4A, &OCR4B, &PORTH, &DDRH, _BV(COM4B1), _BV(PH4), 2},   /* LED 7  D7 */
    {&TCCR4A, &OCR4C, &PORTH, &DDRH, _BV(COM4C1), _BV(PH5), 2},   /* LED 8  D8 */
    {&TCCR5A, &OCR5A, &PORTL, &DDRL, _BV(COM5A1), _BV(PL3), 3},   /* LED 9  D46 */
    {&TCCR5A, &OCR5B, &PORTL, &DDRL, _BV(COM5B1), _BV(PL4), 3},   /* LED 10 D45 */
};

void outputs_init(void)
{
    for (uint8_t i = 0; i < N_LEDS; i++) {
        *CHANNELS[i].port &= (uint8_t)~CHANNELS[i].pin;
        *CHANNELS[i].ddr |= CHANNELS[i].pin;
    }
    for (uint8_t t = 0; t < N_TIMERS; t++) {
        *TIMERS[t].tccrb = 0;
        *TIMERS[t].icr = PWM_TOP;
        *TIMERS[t].tccra = TCCRA_IDLE;
        *TIMERS[t].tccrb = TCCRB_STOPPED;
    }
}

void outputs_dark(void)
{
    for (uint8_t t = 0; t < N_TIMERS; t++)
        *TIMERS[t].tccra = TCCRA_IDLE;                 /* compare outputs off: the pins follow their port bits */
    for (uint8_t i = 0; i < N_LEDS; i++)
        *CHANNELS[i].port &= (uint8_t)~CHANNELS[i].pin;
    for (uint8_t t = 0; t < N_TIMERS; t++)
        *TIMERS[t].tccrb = TCCRB_STOPPED;
}

static uint8_t in_pwm_range(uint16_t pwm)
{
    return pwm != 0 && pwm != 0xFFFFU;
}

void outputs_apply(uint8_t light, const uint16_t *pwm)
{
    if (!light) {
        outputs_dark();
        return;
    }
    uint8_t tccra[N_TIMERS];
    for (uint8_t t = 0; t < N_TIMERS; t++)
        tccra[t] = TCCRA_IDLE;
    for (uint8_t i = 0; i < N_LEDS; i++) {
        const channel_t *c = &CHANNELS[i];
        if (in_pwm_range(pwm[i])) {
            *c->ocr = pwm[i] - 1U;                     /* high for pwm[i] of the PWM_TOP + 1 clocks */
            tccra[c->timer] |= c->com;
        }
    }
    for (uint8_t t = 0; t < N_TIMERS; t++) {
        const pwm_timer_t *tm = &TIMERS[t];
        uint8_t running = (*tm->tccrb & _BV(CS10)) != 0;
        if (!running && tccra[t] != TCCRA_IDLE)
            *tm->tcnt = PWM_TOP;                       /* the next clock is BOTTOM: a period starts now */
        uint8_t dropped = *tm->tccra & (uint8_t)~tccra[t];
        *tm->tccra = tccra[t];
        for (uint8_t i = 0; i < N_LEDS; i++) {         /* port bits of this timer's channels */
            const channel_t *c = &CHANNELS[i];
            if (c->timer != t)
                continue;
            uint8_t was = *c->port;
            uint8_t want = pwm[i] == 0xFFFFU ? (uint8_t)(was | c->pin) : (uint8_t)(was & (uint8_t)~c->pin);
            if (want != was || (dropped & c->com))     /* a disconnected output: its pin takes the port bit */
                *c->port = want;
        }
        if (tccra[t] != TCCRA_IDLE && !running)
            *tm->tccrb = TCCRB_RUNNING;
        else if (tccra[t] == TCCRA_IDLE && running)
            *tm->tccrb = TCCRB_STOPPED;
    }
}
