//! Each kind of token, read through `parse`, with its exact span.

mod common;

use common::render;
use expect_test::{expect, Expect};

fn check(source: &str, expected: Expect) {
    expected.assert_eq(&render(source));
}

#[test]
fn parentheses_and_lists() {
    check(
        "() (a) ( b  c )",
        expect![[r#"
            List @0..2
            List @3..6
              Symbol "a" @4..5
            List @7..15
              Symbol "b" @9..10
              Symbol "c" @12..13
        "#]],
    );
}

#[test]
fn numbers() {
    check(
        "0 440 3.5 3. .5 1e-3 2.5E+4 1E5 007",
        expect![[r#"
            Number 0.0 @0..1
            Number 440.0 @2..5
            Number 3.5 @6..9
            Number 3.0 @10..12
            Number 0.5 @13..15
            Number 0.001 @16..20
            Number 25000.0 @21..27
            Number 100000.0 @28..31
            Number 7.0 @32..35
        "#]],
    );
}

#[test]
fn negative_numbers_and_minus_symbols() {
    // `-` alone and `-` before a non-digit are names; `-` before a digit or
    // `.digit` is a negative literal.
    check(
        "-3 -0.25 -.5 -1e-3 - -x -foo -. (- 3 2) (-3 2)",
        expect![[r#"
            Number -3.0 @0..2
            Number -0.25 @3..8
            Number -0.5 @9..12
            Number -0.001 @13..18
            Symbol "-" @19..20
            Symbol "-x" @21..23
            Symbol "-foo" @24..28
            Symbol "-." @29..31
            List @32..39
              Symbol "-" @33..34
              Number 3.0 @35..36
              Number 2.0 @37..38
            List @40..46
              Number -3.0 @41..43
              Number 2.0 @44..45
        "#]],
    );
}

#[test]
fn symbols() {
    check(
        "t nominal-freq n_f LF-noise + - * / < > = <= >= != empty? set! a.b ... %& ^x ~y x2",
        expect![[r#"
            Symbol "t" @0..1
            Symbol "nominal-freq" @2..14
            Symbol "n_f" @15..18
            Symbol "LF-noise" @19..27
            Symbol "+" @28..29
            Symbol "-" @30..31
            Symbol "*" @32..33
            Symbol "/" @34..35
            Symbol "<" @36..37
            Symbol ">" @38..39
            Symbol "=" @40..41
            Symbol "<=" @42..44
            Symbol ">=" @45..47
            Symbol "!=" @48..50
            Symbol "empty?" @51..57
            Symbol "set!" @58..62
            Symbol "a.b" @63..66
            Symbol "..." @67..70
            Symbol "%&" @71..73
            Symbol "^x" @74..76
            Symbol "~y" @77..79
            Symbol "x2" @80..82
        "#]],
    );
}

#[test]
fn strings_and_escapes() {
    check(
        r#""" "bell.wav" "a \"q\" b\\c\nd\te" "\r\0\u{41}\u{1F600}" "é ü" "two
lines""#,
        expect![[r#"
            Str "" @0..2
            Str "bell.wav" @3..13
            Str "a \"q\" b\\c\nd\te" @14..34
            Str "\r\0A😀" @35..56
            Str "é ü" @57..64
            Str "two\nlines" @65..76
        "#]],
    );
}

#[test]
fn keywords() {
    check(
        "(noise :seed 42 :mix-level .5 :x?)",
        expect![[r#"
            List @0..34
              Symbol "noise" @1..6
              Keyword "seed" @7..12
              Number 42.0 @13..15
              Keyword "mix-level" @16..26
              Number 0.5 @27..29
              Keyword "x?" @30..33
        "#]],
    );
}

#[test]
fn comments_and_whitespace_are_skipped() {
    check(
        "; a whole-line comment\n(a ; trailing (not a list\n\tb)\r\n;last line without newline",
        expect![[r#"
            List @23..52
              Symbol "a" @24..25
              Symbol "b" @50..51
        "#]],
    );
}

#[test]
fn tokens_need_no_space_between_them() {
    check(
        r#"(a"s":k(1)2)"#,
        expect![[r#"
            List @0..12
              Symbol "a" @1..2
              Str "s" @2..5
              Keyword "k" @5..7
              List @7..10
                Number 1.0 @8..9
              Number 2.0 @10..11
        "#]],
    );
}

#[test]
fn empty_and_blank_inputs() {
    check("", expect![""]);
    check("  \n\t ; only a comment", expect![""]);
}
