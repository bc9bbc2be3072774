ardour {
	["type"]    = "dsp",
	name        = "MC Test Notes",
	category    = "Utility",
	license     = "MIT",
	author      = "modal_contact plugin tests",
	description = [[Test note generator for plugin-tests/ardour/test_ardour.py:
emits fixed MIDI note-on/off messages at fixed transport sample positions
(Ardour 7.3's Lua cannot create a MIDI region, so the notes come from this
processor placed before the instrument). The EVENTS table is filled in by
the Python driver; input MIDI is dropped.]]
}

-- { transport sample, status byte, key, velocity }, filled in by test_ardour.py
local EVENTS = {
--@EVENTS@--
}

function dsp_ioconfig ()
	return { { midi_in = 1, midi_out = 1, audio_in = 0, audio_out = 0 }, }
end

function dsp_run (_, _, n_samples)
	assert (type (midiout) == "table")
	-- nothing while the transport stands (the engine keeps running then)
	if not Session:transport_rolling () then return end
	-- the transport position of this cycle's first sample
	local pos = Session:transport_sample ()
	local cnt = 1
	for _, e in ipairs (EVENTS) do
		if e[1] >= pos and e[1] < pos + n_samples then
			-- midiout times are 1-based: time 1 is the cycle's first sample
			midiout[cnt] = { time = e[1] - pos + 1, data = { e[2], e[3], e[4] } }
			cnt = cnt + 1
		end
	end
end
