//! The entropy coder of codec 7's distance residuals (`docs/FORMAT.md`, "Brick payload (codec
//! 7)"): range asymmetric numeral systems (rANS) over static frequency tables, one for each of
//! [`CONTEXTS`] contexts, trained by the writer on the file's first bricks and stored in the
//! file.
//!
//! Why not zstd alone: zstd codes a residual by how often it occurs in the brick, whatever the
//! voxel. How large a residual is likely to be depends on how large its neighbours' were,
//! which a decoder knows before it reads the residual; a table for each class of them codes
//! the VTK gears' distances in about two thirds of zstd's bytes (`docs/PERFORMANCE.md`,
//! "Version 7").
//!
//! Two states of 32 bits take the symbols in turn (the first the even ones, the second the
//! odd ones), each kept in `[2¹⁶, 2³²)` and refilled 16 bits at a time from one stream;
//! frequencies sum to 2¹² in each table. The encoder works backwards over a brick's symbols,
//! so that the decoder reads forwards. Why two: decoding a symbol waits for the one before on
//! the same state (a table look-up, a multiply), and two states let a processor overlap two:
//! a brick decoded in 4.6–4.9 µs instead of 5.0–5.1 (built-in voxmap) and 5.0–5.1 instead of
//! 5.4 (VTK gears), for about three bytes more a brick (the gears' file 1.463 times its
//! version 1 file instead of 1.445, in the form of version 7 measured then). Four states
//! (measured later) took a brick from about 4.1 µs to 3.8–4.0 for five bytes more (1.476
//! instead of 1.438): not kept (`docs/PERFORMANCE.md`, "Version 7").

/// Frequencies of a table sum to `2^PROBABILITY_BITS`.
pub const PROBABILITY_BITS: u32 = 12;

/// What the frequencies of a table sum to.
pub const TOTAL: u32 = 1 << PROBABILITY_BITS;

/// The state's lower bound: a decoder refills below it, and an encoder starts and ends there.
const LOWER: u32 = 1 << 16;

/// Number of contexts, each with its own table.
pub const CONTEXTS: usize = 16;

/// The symbol after which a residual's zigzagged value follows as a raw 16-bit word: for one
/// of 255 or more, or one its context's table does not hold.
pub const ESCAPE: u8 = u8::MAX;

/// One context's table: each symbol's frequency and the start of its slots.
#[derive(Clone)]
pub struct Table {
    frequency: [u16; 256],
    start: [u16; 256],
}

impl Table {
    /// The table of `frequencies` (symbol, frequency), checked as a file's: symbols strictly
    /// increasing, frequencies at least 1, summing to [`TOTAL`].
    fn new(frequencies: &[(u8, u16)]) -> Result<Table, String> {
        let mut table = Table {
            frequency: [0; 256],
            start: [0; 256],
        };
        let mut next = 0u32;
        let mut previous: Option<u8> = None;
        for &(s, f) in frequencies {
            if previous.is_some_and(|p| p >= s) {
                return Err(format!("symbol {s} after symbol {}", previous.unwrap_or(0)));
            }
            if f == 0 || next + u32::from(f) > TOTAL {
                return Err(format!("symbol {s} has frequency {f}, which breaks the total {TOTAL}"));
            }
            table.frequency[s as usize] = f;
            table.start[s as usize] = next as u16;
            next += u32::from(f);
            previous = Some(s);
        }
        if next != TOTAL {
            return Err(format!("frequencies sum to {next}, not {TOTAL}"));
        }
        Ok(table)
    }

    /// Whether the table codes `symbol` itself, rather than by an escape.
    #[inline]
    pub fn holds(&self, symbol: u8) -> bool {
        self.frequency[symbol as usize] > 0
    }
}

/// The tables of all contexts, and for decoding, side by side for all contexts (context `c`'s
/// from `c · TOTAL` and `c · 256`): the symbol of each slot, a byte, and each symbol's
/// frequency less one (bits 0–11) and start (bits 12–23) in one word. A byte a slot keeps
/// the slots of all contexts in 64 KiB, which the first query after opening reads cold.
#[derive(Clone)]
pub struct Tables(Vec<Table>, Box<[u8]>, Box<[u32]>);

impl std::fmt::Debug for Tables {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tables").finish_non_exhaustive()
    }
}

/// Symbol counts of each context, as the writer gathers them to train [`Tables`] on.
pub type Counts = [[u64; 256]; CONTEXTS];

impl Tables {
    /// Tables fitted to `counts`: each symbol seen gets a frequency about proportional to its
    /// count, at least 1, and [`ESCAPE`] always at least 1, so that every residual can be
    /// coded. A context never seen holds the escape alone. The same counts give the same
    /// tables.
    pub fn fit(counts: &Counts) -> Tables {
        let tables = counts.iter().map(|c| {
            let mut c = *c;
            c[ESCAPE as usize] = c[ESCAPE as usize].max(1);
            let total: u64 = c.iter().sum();
            let mut f: Vec<u32> = c
                .iter()
                .map(|&n| {
                    if n == 0 {
                        0
                    } else {
                        ((n * u64::from(TOTAL)) / total).max(1) as u32
                    }
                })
                .collect();
            // Rounding leaves the sum off by a little: take from (or give to) the most frequent
            // symbol that can spare it, one at a time.
            let mut sum: u32 = f.iter().sum();
            while sum != TOTAL {
                let most = (0..256)
                    .filter(|&s| sum < TOTAL || f[s] > 1)
                    .max_by_key(|&s| (f[s], std::cmp::Reverse(s)))
                    .expect("a symbol with a frequency above 1");
                if sum < TOTAL {
                    f[most] += 1;
                    sum += 1;
                } else {
                    f[most] -= 1;
                    sum -= 1;
                }
            }
            let frequencies: Vec<(u8, u16)> = (0..256).filter(|&s| f[s] > 0).map(|s| (s as u8, f[s] as u16)).collect();
            Table::new(&frequencies).expect("fitted frequencies sum to the total")
        });
        Tables::of(tables.collect())
    }

    /// The tables of `tables`, with their look-ups for decoding.
    fn of(tables: Vec<Table>) -> Tables {
        let mut symbols = vec![0u8; CONTEXTS * TOTAL as usize];
        let mut entries = vec![0u32; CONTEXTS * 256];
        for (c, t) in tables.iter().enumerate() {
            for s in (0..256).filter(|&s| t.frequency[s] > 0) {
                let (f, start) = (usize::from(t.frequency[s]), usize::from(t.start[s]));
                symbols[c * TOTAL as usize + start..][..f].fill(s as u8);
                entries[c * 256 + s] = (f as u32 - 1) | (start as u32) << 12;
            }
        }
        Tables(tables, symbols.into(), entries.into())
    }

    /// The table of `context`.
    #[inline(always)]
    pub fn get(&self, context: usize) -> &Table {
        &self.0[context]
    }

    /// The tables as a file stores them: for each context in order, a `u16` count of symbols,
    /// then that many (symbol `u8`, frequency `u16`), little-endian.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for t in &self.0 {
            let held: Vec<usize> = (0..256).filter(|&s| t.frequency[s] > 0).collect();
            out.extend_from_slice(&(held.len() as u16).to_le_bytes());
            for s in held {
                out.push(s as u8);
                out.extend_from_slice(&t.frequency[s].to_le_bytes());
            }
        }
        out
    }

    /// The tables of `bytes`, as [`Tables::to_bytes`] writes them, which they must be exactly:
    /// the error names the first thing wrong.
    pub fn parse(bytes: &[u8]) -> Result<Tables, String> {
        let mut at = 0;
        let mut take = |n: usize| -> Result<&[u8], String> {
            let part = bytes.get(at..at + n).ok_or("the tables end early")?;
            at += n;
            Ok(part)
        };
        let mut tables = Vec::with_capacity(CONTEXTS);
        for context in 0..CONTEXTS {
            let held = u16::from_le_bytes(take(2)?.try_into().expect("2 bytes"));
            if !(1..=256).contains(&held) {
                return Err(format!("context {context} holds {held} symbols, not 1 to 256"));
            }
            let mut frequencies = Vec::with_capacity(held as usize);
            for _ in 0..held {
                let e = take(3)?;
                frequencies.push((e[0], u16::from_le_bytes([e[1], e[2]])));
            }
            tables.push(Table::new(&frequencies).map_err(|e| format!("context {context}: {e}"))?);
        }
        if at != bytes.len() {
            return Err(format!("{} bytes after the tables", bytes.len() - at));
        }
        Ok(Tables::of(tables))
    }
}

/// A brick's symbols, gathered forwards and coded backwards by [`Encoder::finish`].
#[derive(Default)]
pub struct Encoder {
    /// (context, symbol, the raw word after an escape).
    symbols: Vec<(u8, u8, u16)>,
}

impl Encoder {
    /// Code the zigzagged residual `z` in `context`: as its own symbol if the table holds it,
    /// else as an escape and a raw word.
    pub fn push(&mut self, tables: &Tables, context: usize, z: u16) {
        let symbol = match u8::try_from(z) {
            Ok(s) if s != ESCAPE && tables.get(context).holds(s) => s,
            _ => ESCAPE,
        };
        self.symbols.push((context as u8, symbol, z));
    }

    /// The stream of the symbols pushed, appended to `out`: nothing for none; else the final
    /// states (`u32`, the first then the second), then the words (`u16`) in the order a
    /// decoder reads them, little-endian.
    pub fn finish(self, tables: &Tables, out: &mut Vec<u8>) {
        if self.symbols.is_empty() {
            return;
        }
        let mut states = [LOWER; 2];
        let mut words: Vec<u16> = Vec::with_capacity(self.symbols.len() / 2);
        for (j, &(context, symbol, raw)) in self.symbols.iter().enumerate().rev() {
            let x = &mut states[j % 2];
            // The decoder reads a symbol's refill, then its raw word: so, backwards, the raw
            // word first.
            if symbol == ESCAPE {
                words.push(raw);
            }
            let t = tables.get(context as usize);
            let f = u32::from(t.frequency[symbol as usize]);
            if u64::from(*x) >= u64::from(f) << (32 - PROBABILITY_BITS) {
                words.push(*x as u16);
                *x >>= 16;
            }
            *x = ((*x / f) << PROBABILITY_BITS) + *x % f + u32::from(t.start[symbol as usize]);
        }
        out.extend(states.iter().flat_map(|x| x.to_le_bytes()));
        out.extend(words.iter().rev().flat_map(|w| w.to_le_bytes()));
    }
}

/// Reads a stream of [`Encoder::finish`].
pub struct Decoder<'a> {
    /// The state of the next symbol, then the other.
    state: u32,
    other: u32,
    stream: &'a [u8],
    at: usize,
    /// Whether a word was wanted past the end: reported by [`Decoder::finish`], so that the
    /// refill, taken for about one symbol in six at random, needs no branch.
    overrun: bool,
}

impl<'a> Decoder<'a> {
    /// A decoder of `stream`, which holds the two states and then whole words.
    pub fn new(stream: &'a [u8]) -> Result<Decoder<'a>, String> {
        if stream.len() < 8 || !stream.len().is_multiple_of(2) {
            return Err(format!("a distance stream of {} bytes", stream.len()));
        }
        let state = |at: usize| u32::from_le_bytes(stream[at..at + 4].try_into().expect("4 bytes"));
        let (first, second) = (state(0), state(4));
        if first.min(second) < LOWER {
            return Err(format!("a distance stream starting in states {first} and {second}"));
        }
        Ok(Decoder {
            state: first,
            other: second,
            stream,
            at: 8,
            overrun: false,
        })
    }

    /// The next word of the stream if `wanted` (else 0), without a branch on `wanted`.
    #[inline(always)]
    fn word_if(&mut self, wanted: bool) -> u16 {
        let w = match self.stream.get(self.at..self.at + 2) {
            Some(w) => u16::from_le_bytes([w[0], w[1]]),
            None => {
                self.overrun |= wanted;
                0
            }
        };
        self.at += 2 * wanted as usize;
        w & (wanted as u16).wrapping_neg()
    }

    /// The next zigzagged residual, coded with the table of `context` in `tables`. A stream
    /// that ends early gives residuals of 0 from there, and [`Decoder::finish`] the error.
    #[inline(always)]
    pub fn residual(&mut self, tables: &Tables, context: usize) -> u16 {
        let context = context % CONTEXTS;
        let slot = self.state & (TOTAL - 1);
        let s = tables.1[context * TOTAL as usize + slot as usize];
        let e = tables.2[context * 256 + usize::from(s)];
        self.state = ((e & 0xFFF) + 1) * (self.state >> PROBABILITY_BITS) + slot - (e >> 12);
        // A branch, not a select: a select would make the stream's position, and so the next
        // symbol on the other state, wait for this symbol.
        if self.state < LOWER {
            self.state = self.state << 16 | u32::from(self.word_if(true));
        }
        // The next symbol is the other state's.
        std::mem::swap(&mut self.state, &mut self.other);
        if s == ESCAPE {
            self.word_if(true)
        } else {
            u16::from(s)
        }
    }

    /// Check that the stream ended where the encoder began: the whole stream read, and the
    /// state back at its start.
    pub fn finish(self) -> Result<(), String> {
        if self.overrun {
            return Err("the distance stream ends early".into());
        }
        if self.at != self.stream.len() {
            return Err(format!("{} bytes after the distances", self.stream.len() - self.at));
        }
        if self.state != LOWER || self.other != LOWER {
            return Err("the distance stream does not end as it began".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn tables_of(symbols: &[(usize, u16)]) -> Tables {
        let mut counts = [[0u64; 256]; CONTEXTS];
        for &(c, z) in symbols {
            counts[c][usize::from(z).min(255)] += 1;
        }
        Tables::fit(&counts)
    }

    proptest! {
        /// Any residuals in any contexts come back, escapes and all, from tables fitted to
        /// some other residuals: the stream ends where it began, and the tables read back
        /// as they were written.
        #[test]
        fn residuals_come_back(
            train in prop::collection::vec((0..CONTEXTS, 0..40u16), 0..300),
            code in prop::collection::vec((0..CONTEXTS, prop_oneof![0..40u16, any::<u16>()]), 0..600),
        ) {
            let tables = tables_of(&train);
            let tables = Tables::parse(&tables.to_bytes()).unwrap();
            let mut e = Encoder::default();
            for &(c, z) in &code {
                e.push(&tables, c, z);
            }
            let mut stream = Vec::new();
            e.finish(&tables, &mut stream);
            prop_assert_eq!(stream.is_empty(), code.is_empty());
            if !code.is_empty() {
                let mut d = Decoder::new(&stream).unwrap();
                for &(c, z) in &code {
                    prop_assert_eq!(d.residual(&tables, c), z);
                }
                d.finish().unwrap();
            }
        }

        /// Any bytes decode to residuals or to an error, never a panic.
        #[test]
        fn any_stream_decodes_or_fails(stream in prop::collection::vec(any::<u8>(), 0..64), n in 0..40usize) {
            let tables = tables_of(&[(0, 0), (0, 1), (0, 2), (3, 7)]);
            if let Ok(mut d) = Decoder::new(&stream) {
                for i in 0..n {
                    d.residual(&tables, i % CONTEXTS);
                }
                let _ = d.finish();
            }
        }
    }

    /// Fitted tables sum to the total with every seen symbol and the escape held, and a table
    /// that breaks a rule does not parse.
    #[test]
    fn tables_hold_what_was_seen_and_bad_tables_are_refused() {
        let mut counts = [[0u64; 256]; CONTEXTS];
        counts[2][0] = 1_000_000;
        counts[2][1] = 1;
        counts[2][200] = 3;
        let tables = Tables::fit(&counts);
        let t = tables.get(2);
        assert!(t.holds(0) && t.holds(1) && t.holds(200) && t.holds(ESCAPE) && !t.holds(2));
        assert!(tables.get(0).holds(ESCAPE) && !tables.get(0).holds(0));
        let bytes = tables.to_bytes();
        // Context 0 holds the escape alone: a count of 1, symbol 255, frequency 4096.
        assert_eq!(bytes[..5], [1, 0, 255, 0, 16]);
        let mut bad = bytes.clone();
        bad[3] = 1; // the escape's frequency 4097
        assert!(Tables::parse(&bad).unwrap_err().contains("context 0"));
        assert!(Tables::parse(&bytes[..bytes.len() - 1]).is_err());
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(Tables::parse(&longer).is_err());
        assert!(Tables::parse(&bytes).is_ok());
    }
}
