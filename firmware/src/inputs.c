/* Sensors (board.h has the pins): current sense comparators, driver fault flags, LM35 on ADC0. */
#include <avr/io.h>
#include "board.h"
#include "inputs.h"

typedef struct {
    volatile uint8_t *pin;
    uint8_t bit;
} input_t;

static const input_t SENSE[N_LEDS] = {
    {&PINA, _BV(PA0)}, {&PINA, _BV(PA1)}, {&PINA, _BV(PA2)}, {&PINA, _BV(PA3)}, {&PINA, _BV(PA4)},
    {&PINA, _BV(PA5)}, {&PINA, _BV(PA6)}, {&PINA, _BV(PA7)}, {&PINC, _BV(PC0)}, {&PINC, _BV(PC1)},
};

static const input_t FAULT[N_LEDS] = {
    {&PINK, _BV(PK0)}, {&PINK, _BV(PK1)}, {&PINK, _BV(PK2)}, {&PINK, _BV(PK3)}, {&PINK, _BV(PK4)},
    {&PINK, _BV(PK5)}, {&PINK, _BV(PK6)}, {&PINK, _BV(PK7)}, {&PINC, _BV(PC2)}, {&PINC, _BV(PC3)},
};

static uint16_t sample_sum;
static uint8_t samples;

void inputs_init(void)
{
    DDRA = 0;                           /* sense: inputs, pulled up on the board (open-collector comparators) */
    PORTA = 0;
    DDRK = 0;                           /* driver fault flags: inputs with the internal pull-ups */
    PORTK = 0xFF;
    DDRC &= (uint8_t)~(_BV(PC0) | _BV(PC1) | _BV(PC2) | _BV(PC3));
    PORTC = (uint8_t)((PORTC & (uint8_t)~(_BV(PC0) | _BV(PC1))) | _BV(PC2) | _BV(PC3));
    DIDR0 = _BV(ADC0D);                 /* the analog input needs no digital buffer */
    ADMUX = _BV(REFS1) | TEMP_ADC_CHANNEL;          /* internal 1.1 V reference, ADC0 */
    ADCSRB = 0;
    ADCSRA = _BV(ADEN) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0);   /* 125 kHz ADC clock: 104 us a conversion */
}

static int16_t centi_of(uint16_t sum)
{
    /* LM35: 10 mV per degree; 1.1 V / 1024 per count: T (1/100 C) = counts x 11000 / 1024, over 16 samples */
    return (int16_t)(((uint32_t)sum * 11000UL + 8192UL) / (1024UL * TEMP_SAMPLES));
}

int16_t inputs_first_temperature(void)
{
    uint16_t sum = 0;
    for (uint8_t i = 0; i < TEMP_SAMPLES; i++) {
        ADCSRA |= _BV(ADSC);
        while (ADCSRA & _BV(ADSC))
            ;
        sum += ADC;
    }
    ADCSRA |= _BV(ADSC);                /* the tick takes the next one */
    return centi_of(sum);
}

uint8_t inputs_tick(int16_t *centi)
{
    if (ADCSRA & _BV(ADSC))
        return 0;                       /* still converting (cannot happen at 1 kHz: a conversion takes 104 us) */
    sample_sum += ADC;
    ADCSRA |= _BV(ADSC);
    if (++samples < TEMP_SAMPLES)
        return 0;
    *centi = centi_of(sample_sum);
    sample_sum = 0;
    samples = 0;
    return 1;
}

uint8_t inputs_driver_fault(uint8_t led)
{
    return (*FAULT[led].pin & FAULT[led].bit) == 0;
}

uint8_t inputs_current(uint8_t led)
{
    return (*SENSE[led].pin & SENSE[led].bit) != 0;
}
