"""A shared assertion for the benchmark scripts' bad-input tests."""

import contextlib
import io


class RefusalAssertions:
    """Mixin for a unittest.TestCase whose `main` attribute is a script's
    main(argv) function (set as a staticmethod)."""

    def assertRefused(self, argv, *fragments):
        """main(argv) exits with 2, its error naming every fragment."""
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            code = self.main(list(argv))
        self.assertEqual(code, 2, argv)
        for fragment in fragments:
            self.assertIn(fragment, err.getvalue())
