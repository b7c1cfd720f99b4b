//! The `[bind]` expression parser on arbitrary text, then evaluation at a few symbol values.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ribbon::uncertainty::Expression;

const SYMBOLS: [&str; 3] = ["l1", "l2", "m"];

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(expression) = Expression::parse(text, &SYMBOLS) {
        for values in [[1.0, 2.0, 0.5], [0.0, -1.0, 1e300]] {
            let _ = expression.eval_with(&values);
        }
    }
});
