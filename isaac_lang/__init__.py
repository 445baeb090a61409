"""isaac_lang: the front end. Scene text -> parse tree -> IR; diagnostics; the command line."""
