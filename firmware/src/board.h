/* The board: an Arduino Mega 2560 (ATmega2560, 16 MHz) driving the 10-LED sphere (firmware/README.md has the
 * wiring and the bill of materials). Every pin the firmware touches is named here and nowhere else. */
#ifndef BOARD_H
#define BOARD_H

#include <stdint.h>

#define SPHERE_MODEL "DRGB-SPHERE10"
#ifndef SPHERE_SERIAL
#define SPHERE_SERIAL "SN0001"          /* the EEPROM's default; make SERIAL=SN0042 sets another */
#endif

#define N_LEDS 10                       /* LED 1 = 416 nm ... LED 10 = 680 nm (thesis Table 4.2) */

/* 16-bit fast PWM (mode 14, TOP = ICRn): a period of PWM_TOP + 1 = 65535 clocks, 4.096 ms (244 Hz) at
 * 16 MHz. Level p (1..65534) compares at OCR = p - 1: the pin is high for exactly p of the 65535 clocks, the
 * protocol's level p / 65535. p = 65535 is the pin held high (no PWM), p = 0 the pin held low. */
#define PWM_TOP 65534U

/* PWM outputs, LED 1..10: timer, compare unit, Arduino pin (the wiring note in firmware/README.md)
 *   LED 1  OC1A PB5 D11    LED 2  OC1B PB6 D12
 *   LED 3  OC3A PE3 D5     LED 4  OC3B PE4 D2     LED 5  OC3C PE5 D3
 *   LED 6  OC4A PH3 D6     LED 7  OC4B PH4 D7     LED 8  OC4C PH5 D8
 *   LED 9  OC5A PL3 D46    LED 10 OC5B PL4 D45
 * Each line has a 10 kOhm pull-down on the board: at reset, in brown-out and before the firmware runs the pins
 * are inputs, and the pull-down holds the LED switch off. */

/* LED current sense, LED 1..10 (input, high = current flowed in the last ~10 ms; comparator with peak hold):
 *   LED 1..8 PA0..PA7 (D22..D29), LED 9 PC0 (D37), LED 10 PC1 (D36) */
/* LED driver fault flag, LED 1..10 (input, active low, internal pull-up: unconnected = no fault):
 *   LED 1..8 PK0..PK7 (A8..A15), LED 9 PC2 (D35), LED 10 PC3 (D34) */

/* A driven channel counts as open-circuit (FAULT?) once it has been driven this long without current; FAULT? and
 * STATUS? wait for it (at most this long) so that a fault is reported right after ON, as the protocol says. */
#define SENSE_SETTLE_MS 10U
/* Below this PWM value (0.25 %: 10 us pulses at 244 Hz) the sense comparator cannot see the pulses: such a
 * channel is not judged by its current (its driver's fault flag still counts). */
#define SENSE_MIN_PWM 164U

/* Temperature: an LM35 (10 mV per degree C) on A0 (PF0, ADC0) against the internal 1.1 V reference. */
#define TEMP_ADC_CHANNEL 0
#define TEMP_SAMPLES 16                 /* one reading = the mean of 16 conversions, one per millisecond */
#define OVER_TEMPERATURE_CENTI 4500     /* 45.00 C: LIGHT 1 / ON refused (ERR 7) and a lit sphere switched off */

/* The tick: Timer0, CTC, 16 MHz / 64 / 250 = 1 kHz. The watchdog, the ON <ms> limit and the over-temperature
 * switch-off are decided in its interrupt, whatever the main loop is doing. */
#define TICK_OCR 249

#endif
